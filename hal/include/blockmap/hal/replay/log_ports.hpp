// Ports over recorded device logs (docs/log-formats.md), for `blockmap replay`: the same
// devices and decoders as on the robot read the recorded bytes and frames. A log is read in
// fixed-size pieces as it is consumed, so a replay's memory does not grow with the log.
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "blockmap/core/time.hpp"
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

// The recorded times of one device's log, as a damaged byte can turn them: a time that jumps
// away from the last good one is that record's fault and takes the last good time, unless the
// records after it keep the jump, which is then the device's clock stepping (or the device
// falling silent a while) and is kept. Never the end of the log.
class RecordedTimes {
 public:
  // Forward gaps up to this, and steps back up to kMaxBackNs, are a device's own (the RMP
  // sends every 10 ms, a laser's reads come every few).
  static constexpr TimestampNs kMaxGapNs = kNanosecondsPerSecond / 4;
  static constexpr TimestampNs kMaxBackNs = kNanosecondsPerSecond / 20;
  // A jump is the clock's when this many records after it keep it.
  static constexpr std::size_t kConfirming = 3;

  // The time to give a record stamped `stamp_ns`, given the times of the (up to kConfirming)
  // records after it; none when the record is to be dropped (a first record most of whose
  // successors do not follow it).
  [[nodiscard]] std::optional<TimestampNs> judge(TimestampNs stamp_ns,
                                                 std::span<const TimestampNs> next_ns) noexcept;
  [[nodiscard]] std::uint64_t faults() const noexcept { return faults_; }
  [[nodiscard]] std::uint64_t steps() const noexcept { return steps_; }
  // Whether `later_ns` lies where a record's time after one at `earlier_ns` can.
  [[nodiscard]] static bool follows(TimestampNs earlier_ns, TimestampNs later_ns) noexcept;

 private:
  // Whether at least half of `next_ns` lie where they would after `stamp_ns`.
  [[nodiscard]] static bool most_follow(TimestampNs stamp_ns,
                                        std::span<const TimestampNs> next_ns) noexcept;
  // Whether each of `next_ns` follows the one before it, from `stamp_ns`.
  [[nodiscard]] static bool kept(TimestampNs stamp_ns,
                                 std::span<const TimestampNs> next_ns) noexcept;

  std::optional<TimestampNs> last_ns_;
  std::uint64_t faults_ = 0;
  std::uint64_t steps_ = 0;
};

// A candump log (can-utils' `(sec.usec) can0 401#...` lines) as a CanBus: each receive()
// returns the next frame with its recorded time. Blank and comment lines are skipped; a line
// that is not a frame is counted and skipped (the first one's number is kept for the report).
// Times are judged by RecordedTimes, one frame read ahead. kClosed at the end of the log.
// Filters apply as on SocketCAN; send() is refused.
class CandumpFileBus final : public CanBus {
 public:
  explicit CandumpFileBus(const std::string& path);
  [[nodiscard]] bool ok() const noexcept { return file_.ok(); }
  [[nodiscard]] const std::string& error() const noexcept { return file_.error(); }
  [[nodiscard]] std::uint64_t lines_read() const noexcept { return lines_; }
  [[nodiscard]] std::uint64_t lines_rejected() const noexcept { return rejected_; }
  [[nodiscard]] std::uint64_t first_rejected_line() const noexcept { return first_rejected_; }
  [[nodiscard]] const RecordedTimes& times() const noexcept { return times_; }

 protected:
  CanReceiveResult do_receive(CanFrame& frame, TimestampNs timeout_ns) override;
  IoStatus do_send(const CanFrame& frame) override;
  IoStatus do_set_filters(std::span<const CanFilter> filters) override;

 private:
  static constexpr std::size_t kMaxFilters = 16;
  [[nodiscard]] bool accepted(const CanFrame& frame) const noexcept;
  // The next frame the filters accept, as recorded; false at the end.
  bool read_frame(CanFrame& frame, TimestampNs& stamp_ns);

  LogFile file_;
  RecordedTimes times_;
  // The frames read ahead, whose times judge the first's.
  std::array<CanFrame, RecordedTimes::kConfirming + 1> ahead_{};
  std::array<TimestampNs, RecordedTimes::kConfirming + 1> ahead_ns_{};
  std::size_t ahead_count_ = 0;
  bool ended_ = false;
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
// skipped. A damaged record (a header that cannot be one) is skipped: the reader looks on for
// the next place where two records in a row read well and carry times near the last good
// one, and goes on from there, counting the places and bytes it skipped (a damaged magic or
// last record too). Times are judged by RecordedTimes. A log cut off inside a record ends
// with kIoError, reported by damage().
// One record is in memory at a time.
class ByteLogFileStream final : public ByteStream {
 public:
  explicit ByteLogFileStream(const std::string& path);
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  // kNone, or why the log ended early, and where (bytes from the start of the file).
  [[nodiscard]] protocol::byte_log::ParseError damage() const noexcept { return damage_; }
  [[nodiscard]] std::uint64_t damage_offset() const noexcept { return damage_offset_; }
  // Damaged places skipped, the bytes skipped over them, and the first one's offset and why.
  [[nodiscard]] std::uint64_t skipped_places() const noexcept { return skipped_places_; }
  [[nodiscard]] std::uint64_t skipped_bytes() const noexcept { return skipped_bytes_; }
  [[nodiscard]] std::uint64_t first_skip_offset() const noexcept { return first_skip_offset_; }
  [[nodiscard]] protocol::byte_log::ParseError first_skip() const noexcept { return first_skip_; }
  [[nodiscard]] const RecordedTimes& times() const noexcept { return times_; }

 protected:
  ReadResult do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;

 private:
  struct Header {
    protocol::byte_log::RecordHeader fields;
    protocol::byte_log::ParseError error = protocol::byte_log::ParseError::kNone;
  };
  // `out.size()` bytes from `offset`, through a window read ahead; false past the file's end.
  bool read_at(std::uint64_t offset, std::span<std::uint8_t> out) const;
  // The header at `offset` as read (error kEnd at the file's end).
  [[nodiscard]] Header header_at(std::uint64_t offset) const;
  // Whether a record can start at `offset` where the reader looks again after damage: its
  // header reads well and the record after it does too (or the file ends with it); with
  // `near_ns`, their times lie near it and each other.
  [[nodiscard]] bool record_starts_at(std::uint64_t offset,
                                      std::optional<TimestampNs> near_ns) const;
  [[nodiscard]] static bool near(TimestampNs before_ns, TimestampNs stamp_ns) noexcept;
  // The first place in [from, until) where a record starts after damage, if any.
  [[nodiscard]] std::optional<std::uint64_t> next_record_start(std::uint64_t from,
                                                               std::uint64_t until);
  // From the damaged place at offset_, on to the next place a record starts; false when none.
  bool resynchronise(protocol::byte_log::ParseError why);
  // Counts the damaged place from offset_ to `to`.
  void note_skip(protocol::byte_log::ParseError why, std::uint64_t to) noexcept;
  // Why the record at `offset`, whose header reads well and whose successor starts at `next`,
  // is not as long as it says; kNone when it is: the record after it reads well at a time
  // that closely follows, or the file ends with it, or no record starts inside it.
  [[nodiscard]] protocol::byte_log::ParseError length_fault(std::uint64_t offset,
                                                            const Header& header,
                                                            std::uint64_t next);
  // Loads the next device record; false at the end or on damage that ends the log.
  bool load_next();

  LogFile file_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
  std::string error_;
  std::vector<std::uint8_t> record_;  // the current record's bytes
  std::vector<std::uint8_t> window_;  // where a damaged log is searched for the next record
  // The file from ahead_from_ on, read in one call for the records and headers in it.
  mutable std::vector<std::uint8_t> read_ahead_;
  mutable std::uint64_t ahead_from_ = 0;
  mutable std::size_t ahead_bytes_ = 0;
  std::size_t consumed_ = 0;  // of them, already handed out
  TimestampNs stamp_ns_ = 0;
  std::optional<TimestampNs> last_good_ns_;  // the last record's time as judged
  std::uint64_t offset_ = 0;                 // of the next record in the file
  bool ended_ = false;
  RecordedTimes times_;
  protocol::byte_log::ParseError damage_ = protocol::byte_log::ParseError::kNone;
  std::uint64_t damage_offset_ = 0;
  std::uint64_t skipped_places_ = 0;
  std::uint64_t skipped_bytes_ = 0;
  std::uint64_t first_skip_offset_ = 0;
  protocol::byte_log::ParseError first_skip_ = protocol::byte_log::ParseError::kNone;
};

}  // namespace blockmap::hal::replay
