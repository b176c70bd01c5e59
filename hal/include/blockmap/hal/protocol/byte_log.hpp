// The timestamped byte log: how blockmap records a serial or USB device's raw bytes with their
// receive times (the format is documented in docs/log-formats.md, "Timestamped byte log"). A
// file is the 8-byte magic "BMBYTES1" and then records, each a 16-byte header and the bytes one
// read returned:
//
//   offset 0  int64  LE  receive time, ns (the time base of the run: Unix time for recordings)
//   offset 8  uint32 LE  byte count n (at most kMaxRecordBytes)
//   offset 12 uint8      direction: 0 device -> host, 1 host -> device
//   offset 13 3 bytes    zero (reserved)
//   offset 16 n bytes    the bytes, exactly as read or written
//
// Records are in time order. Pure functions, no I/O, no heap.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "blockmap/core/time.hpp"

namespace blockmap::hal::protocol::byte_log {

inline constexpr std::array<std::uint8_t, 8> kMagic = {'B', 'M', 'B', 'Y', 'T', 'E', 'S', '1'};
inline constexpr std::size_t kRecordHeaderBytes = 16;
inline constexpr std::uint32_t kMaxRecordBytes = 1U << 20;

enum class Direction : std::uint8_t { kFromDevice = 0, kToDevice = 1 };

struct RecordHeader {
  TimestampNs stamp_ns = 0;
  std::uint32_t length = 0;
  Direction direction = Direction::kFromDevice;
};

struct Record {
  RecordHeader header;
  std::span<const std::uint8_t> bytes;
};

enum class ParseError : std::uint8_t {
  kNone = 0,
  kEnd,              // no more records (not an error)
  kTruncatedHeader,  // fewer than 16 bytes left
  kTruncatedData,    // the header promises more bytes than the file holds
  kBadDirection,     // a direction other than 0 or 1
  kBadReserved,      // reserved bytes not zero (not a byte log, or a newer format)
  kTooLong,          // a record longer than kMaxRecordBytes
  kBadLength,        // records start inside this one's bytes (found by a reader that looks)
  kBadMagic,         // a file whose records read well but whose magic is damaged
};
[[nodiscard]] const char* to_string(ParseError error) noexcept;

// True when `file` starts with the magic.
[[nodiscard]] bool has_magic(std::span<const std::uint8_t> file) noexcept;

// Writes the 16-byte header of a record.
void encode_record_header(const RecordHeader& header,
                          std::span<std::uint8_t, kRecordHeaderBytes> out) noexcept;

// Reads a record's 16-byte header, checking what a header alone can show (direction,
// reserved bytes, length). kNone or the error; `header` is set when kNone.
[[nodiscard]] ParseError decode_record_header(
    std::span<const std::uint8_t, kRecordHeaderBytes> bytes, RecordHeader& header) noexcept;

// Reads the records of a whole log held in memory (the magic is checked by the caller).
class Reader {
 public:
  // `records` is the file after its magic.
  explicit Reader(std::span<const std::uint8_t> records) noexcept : rest_(records) {}

  // The next record, kEnd at the end, or an error (after which the reader stays at the error).
  ParseError next(Record& record) noexcept;
  // Offset of the next record from the start of `records`.
  [[nodiscard]] std::size_t offset() const noexcept { return offset_; }

 private:
  std::span<const std::uint8_t> rest_;
  std::size_t offset_ = 0;
};

}  // namespace blockmap::hal::protocol::byte_log
