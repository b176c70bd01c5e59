// can-utils' candump log format (docs/log-formats.md): one frame a line,
//   (1436509052.249713) can0 401#FFF9000FFFFF0009
// so that real captures replay with canplayer and blockmap's logs read in candump tools.
// Pure text functions: no I/O, no heap.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <string_view>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/can_frame.hpp"

namespace blockmap::hal::protocol::candump {

struct Record {
  TimestampNs stamp_ns = 0;           // the log's timestamp (seconds.microseconds), in ns
  std::array<char, 16> interface {};  // "can0", NUL-terminated
  CanFrame frame;
};

enum class ParseError : std::uint8_t {
  kNone = 0,
  kNotAFrame,      // a blank line or a comment ('#')
  kBadTimestamp,   // not "(seconds.microseconds)"
  kBadInterface,   // missing or longer than 15 characters
  kBadIdentifier,  // not 3 (standard) or 8 (extended) hex digits, or out of range
  kBadData,        // odd hex digits, more than 8 bytes, or CAN FD ("##")
};
[[nodiscard]] const char* to_string(ParseError error) noexcept;

// Parses one line (without its line end) of a candump log.
[[nodiscard]] ParseError parse_line(std::string_view line, Record& record) noexcept;

// Also reads the plain "id:0401 FF F9 00 0F FF FF 00 09" lines of older loggers (Orca's RMP
// captures); these carry no time, so stamp_ns is left as it is.
[[nodiscard]] ParseError parse_id_bytes_line(std::string_view line, Record& record) noexcept;

// Writes the candump line of `record` (no line end) into `out`; returns its length, or 0 when
// `out` is too small (64 bytes always suffice).
[[nodiscard]] std::size_t format_line(const Record& record, std::span<char> out) noexcept;

}  // namespace blockmap::hal::protocol::candump
