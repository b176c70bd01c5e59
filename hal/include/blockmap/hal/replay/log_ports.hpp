// Ports over recorded device logs (docs/log-formats.md), for `blockmap replay`: the same
// devices and decoders as on the robot read the recorded bytes and frames. A log is read in
// fixed-size pieces as it is consumed, so a replay's memory does not grow with the log.
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "blockmap/hal/byte_stream.hpp"
#include "blockmap/hal/can_bus.hpp"
#include "blockmap/hal/protocol/byte_log.hpp"

namespace blockmap::hal::replay {

// A file closed on destruction.
class LogFile {
 public:
  // Opens `path` for reading; ok() says whether that worked, error() why not.
  explicit LogFile(const std::string& path);
  LogFile(const LogFile&) = delete;
  LogFile& operator=(const LogFile&) = delete;
  ~LogFile();
  [[nodiscard]] bool ok() const noexcept { return file_ != nullptr; }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  [[nodiscard]] std::FILE* get() const noexcept { return file_; }

 private:
  std::FILE* file_ = nullptr;
  std::string error_;
};

// A candump log (can-utils' `(sec.usec) can0 401#...` lines) as a CanBus: each receive()
// returns the next frame with its recorded time. Blank and comment lines are skipped; a line
// that is not a frame is counted and skipped (the first one's number is kept for the report).
// kClosed at the end of the log. Filters apply as on SocketCAN; send() is refused.
class CandumpFileBus final : public CanBus {
 public:
  explicit CandumpFileBus(const std::string& path);
  [[nodiscard]] bool ok() const noexcept { return file_.ok(); }
  [[nodiscard]] const std::string& error() const noexcept { return file_.error(); }
  [[nodiscard]] std::uint64_t lines_read() const noexcept { return lines_; }
  [[nodiscard]] std::uint64_t lines_rejected() const noexcept { return rejected_; }
  [[nodiscard]] std::uint64_t first_rejected_line() const noexcept { return first_rejected_; }

 protected:
  CanReceiveResult do_receive(CanFrame& frame, TimestampNs timeout_ns) override;
  IoStatus do_send(const CanFrame& frame) override;
  IoStatus do_set_filters(std::span<const CanFilter> filters) override;

 private:
  static constexpr std::size_t kMaxFilters = 16;
  [[nodiscard]] bool accepted(const CanFrame& frame) const noexcept;

  LogFile file_;
  std::array<char, 256> line_{};  // a candump line is at most about 60 characters
  std::array<CanFilter, kMaxFilters> filters_{};
  std::size_t filter_count_ = 0;
  std::uint64_t lines_ = 0;
  std::uint64_t rejected_ = 0;
  std::uint64_t first_rejected_ = 0;
};

// A raw byte stream from a file (an NMEA receiver's log) as a ByteStream. The bytes carry no
// receive times: reads are stamped 0, and the messages' own times (NMEA's UTC) line them up.
// kClosed at the end of the file; writes are refused.
class FileByteStream final : public ByteStream {
 public:
  explicit FileByteStream(const std::string& path);
  [[nodiscard]] bool ok() const noexcept { return file_.ok(); }
  [[nodiscard]] const std::string& error() const noexcept { return file_.error(); }

 protected:
  ReadResult do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;

 private:
  LogFile file_;
};

// A timestamped byte log (docs/log-formats.md: a laser's telegrams as the host read them) as a
// ByteStream: each read returns the device's bytes of the next record (or as much as the
// caller's buffer holds) stamped with the record's receive time; the host's own writes are
// skipped. A damaged record ends the stream (kIoError) and is reported by damage(): the
// records before it are all delivered. One record is in memory at a time.
class ByteLogFileStream final : public ByteStream {
 public:
  explicit ByteLogFileStream(const std::string& path);
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  // kNone, or why the log ended early, and where (bytes from the start of the file).
  [[nodiscard]] protocol::byte_log::ParseError damage() const noexcept { return damage_; }
  [[nodiscard]] std::uint64_t damage_offset() const noexcept { return damage_offset_; }

 protected:
  ReadResult do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;

 private:
  // Loads the next device record; false at the end or on damage.
  bool load_next();

  LogFile file_;
  std::string error_;
  std::vector<std::uint8_t> record_;  // header and bytes of the current record
  std::size_t consumed_ = 0;          // of its bytes, already handed out
  std::size_t length_ = 0;
  TimestampNs stamp_ns_ = 0;
  std::uint64_t offset_ = 0;  // of the next record in the file
  bool ended_ = false;
  protocol::byte_log::ParseError damage_ = protocol::byte_log::ParseError::kNone;
  std::uint64_t damage_offset_ = 0;
};

}  // namespace blockmap::hal::replay
