// CaptureReader: a capture for `blockmap decode`, read piece by piece in constant memory
// whatever its length: a raw byte stream (a piece per read, no time), or the device-to-host
// records of a timestamped byte log (docs/log-formats.md), each with its receive time. A
// damaged byte-log record ends the log there; what came before it has been handed out.
#pragma once

#include <cstdint>
#include <cstdio>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/replay/log_ports.hpp"

namespace blockmap::cli {

class CaptureReader {
 public:
  explicit CaptureReader(std::string path);
  CaptureReader(const CaptureReader&) = delete;
  CaptureReader& operator=(const CaptureReader&) = delete;

  // Opens the capture ("-" is standard input): empty when it could, else one line why not.
  [[nodiscard]] std::string open();
  // The next piece of the device's bytes and when it was received (0 in a raw stream); false
  // at the end, or where a byte log is damaged or reading failed (then damage() says so).
  bool next(std::span<const std::uint8_t>& bytes, TimestampNs& stamp_ns);

  [[nodiscard]] const std::string& path() const noexcept { return path_; }
  // Whether the pieces carry receive times (a byte log).
  [[nodiscard]] bool timed() const noexcept { return timed_; }
  // The host's own records of a byte log, skipped (a laser's start request).
  [[nodiscard]] std::size_t host_records() const noexcept { return host_records_; }
  // Empty, or one line: where the byte log is damaged, or why reading failed.
  [[nodiscard]] const std::string& damage() const noexcept { return damage_; }

 private:
  // Fills `out` from the file, less only at its end; false on a read error.
  bool read_fully(std::span<std::uint8_t> out, std::size_t& got);
  bool next_record(std::span<const std::uint8_t>& bytes, TimestampNs& stamp_ns);

  std::string path_;
  std::optional<hal::replay::LogFile> log_;  // a file; standard input is not one
  std::FILE* file_ = nullptr;
  bool timed_ = false;
  bool ended_ = false;
  std::vector<std::uint8_t> buffer_;  // one read, or one record: at most a record's size
  std::size_t held_ = 0;              // bytes read ahead (the magic's test) to hand out first
  std::uint64_t offset_ = 0;          // of the next byte in the file
  std::size_t host_records_ = 0;
  std::string damage_;
};

}  // namespace blockmap::cli
