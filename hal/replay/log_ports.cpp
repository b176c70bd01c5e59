#include "blockmap/hal/replay/log_ports.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <string_view>
#include <system_error>
#include <utility>

#include "blockmap/hal/files.hpp"
#include "blockmap/hal/protocol/candump.hpp"

namespace blockmap::hal::replay {

LogFile::LogFile(const std::string& path) {
  // A folder opens, and reads as an error later: it is refused here, by name.
  if (std::string problem = unreadable_file(path); !problem.empty()) {
    error_ = std::move(problem);
    return;
  }
  file_ = std::fopen(path.c_str(), "rb");
  if (file_ == nullptr) {
    error_ = path + ": " + std::generic_category().message(errno);
  }
}

LogFile::~LogFile() {
  if (file_ != nullptr) {
    static_cast<void>(std::fclose(file_));
  }
}

namespace {

// Whether `later_ns` lies from `max_back_ns` before `earlier_ns` to `max_ahead_ns` after it;
// a damaged time can be any 64-bit number, so the difference is checked for overflow.
bool within(TimestampNs earlier_ns, TimestampNs later_ns, TimestampNs max_back_ns,
            TimestampNs max_ahead_ns) noexcept {
  TimestampNs gap_ns = 0;
  return !__builtin_sub_overflow(later_ns, earlier_ns, &gap_ns) && gap_ns >= -max_back_ns &&
         gap_ns <= max_ahead_ns;
}

}  // namespace

CandumpFileBus::CandumpFileBus(const std::string& path) : file_(path) {}

std::optional<TimestampNs> RecordedTimes::judge(TimestampNs stamp_ns,
                                                std::span<const TimestampNs> next_ns) noexcept {
  if (!last_ns_) {
    if (!most_follow(stamp_ns, next_ns)) {
      ++faults_;
      return std::nullopt;
    }
    last_ns_ = stamp_ns;
    return stamp_ns;
  }
  if (follows(*last_ns_, stamp_ns)) {
    // Near the last, but off the next that the last leads to: a smaller jump, still a fault.
    if (!next_ns.empty() && !follows(stamp_ns, next_ns[0]) && follows(*last_ns_, next_ns[0])) {
      ++faults_;
      return *last_ns_;
    }
    last_ns_ = stamp_ns;
    return stamp_ns;
  }
  // A step is kept when the records after it follow the new time and not the old one.
  if (next_ns.size() < kConfirming || !kept(stamp_ns, next_ns) || follows(*last_ns_, next_ns[0])) {
    ++faults_;
    return *last_ns_;
  }
  ++steps_;
  last_ns_ = stamp_ns;
  return stamp_ns;
}

bool RecordedTimes::most_follow(TimestampNs stamp_ns,
                                std::span<const TimestampNs> next_ns) noexcept {
  std::size_t following = 0;
  for (std::size_t i = 0; i < next_ns.size(); ++i) {
    if (within(stamp_ns, next_ns[i], kMaxBackNs, static_cast<TimestampNs>(i + 1) * kMaxGapNs)) {
      ++following;
    }
  }
  return 2 * following >= next_ns.size();
}

bool RecordedTimes::kept(TimestampNs stamp_ns, std::span<const TimestampNs> next_ns) noexcept {
  TimestampNs before_ns = stamp_ns;
  for (const TimestampNs after_ns : next_ns) {
    if (!follows(before_ns, after_ns)) {
      return false;
    }
    before_ns = after_ns;
  }
  return true;
}

bool RecordedTimes::follows(TimestampNs earlier_ns, TimestampNs later_ns) noexcept {
  return within(earlier_ns, later_ns, kMaxBackNs, kMaxGapNs);
}

CanReceiveResult CandumpFileBus::do_receive(CanFrame& frame, TimestampNs /*timeout_ns*/) {
  if (!file_.ok()) {
    return {IoStatus::kClosed, 0};
  }
  while (true) {
    while (!ended_ && ahead_count_ < ahead_.size()) {
      ended_ = !read_frame(ahead_[ahead_count_], ahead_ns_[ahead_count_]);
      ahead_count_ += ended_ ? 0 : 1;
    }
    if (ahead_count_ == 0) {
      return {IoStatus::kClosed, 0};
    }
    const CanFrame current = ahead_[0];
    const std::optional<TimestampNs> judged = times_.judge(
        ahead_ns_[0], std::span<const TimestampNs>(ahead_ns_).subspan(1, ahead_count_ - 1));
    std::copy(ahead_.begin() + 1, ahead_.begin() + static_cast<std::ptrdiff_t>(ahead_count_),
              ahead_.begin());
    std::copy(ahead_ns_.begin() + 1, ahead_ns_.begin() + static_cast<std::ptrdiff_t>(ahead_count_),
              ahead_ns_.begin());
    --ahead_count_;
    if (judged) {
      frame = current;
      return {IoStatus::kOk, *judged};
    }
  }
}

bool CandumpFileBus::read_frame(CanFrame& frame, TimestampNs& stamp_ns) {
  while (std::fgets(line_.data(), static_cast<int>(line_.size()), file_.get()) != nullptr) {
    ++lines_;
    std::string_view text(line_.data());
    const bool whole_line = !text.empty() && text.back() == '\n';
    if (!whole_line && std::feof(file_.get()) == 0) {
      // Longer than any candump line: skip the rest of it and count it.
      int c = 0;
      while ((c = std::fgetc(file_.get())) != EOF && c != '\n') {
      }
      ++rejected_;
      first_rejected_ = first_rejected_ == 0 ? lines_ : first_rejected_;
      continue;
    }
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) {
      text.remove_suffix(1);
    }
    protocol::candump::Record record;
    const protocol::candump::ParseError parsed = protocol::candump::parse_line(text, record);
    if (parsed == protocol::candump::ParseError::kNotAFrame) {
      continue;
    }
    if (parsed != protocol::candump::ParseError::kNone) {
      ++rejected_;
      first_rejected_ = first_rejected_ == 0 ? lines_ : first_rejected_;
      continue;
    }
    if (!accepted(record.frame)) {
      continue;
    }
    frame = record.frame;
    stamp_ns = record.stamp_ns;
    return true;
  }
  return false;
}

IoStatus CandumpFileBus::do_send(const CanFrame& /*frame*/) {
  return IoStatus::kInvalidArgument;
}

IoStatus CandumpFileBus::do_set_filters(std::span<const CanFilter> filters) {
  if (filters.size() > kMaxFilters) {
    return IoStatus::kInvalidArgument;
  }
  std::copy(filters.begin(), filters.end(), filters_.begin());
  filter_count_ = filters.size();
  return IoStatus::kOk;
}

bool CandumpFileBus::accepted(const CanFrame& frame) const noexcept {
  if (filter_count_ == 0) {
    return true;
  }
  return std::any_of(filters_.begin(),
                     filters_.begin() + static_cast<std::ptrdiff_t>(filter_count_),
                     [&](const CanFilter& f) { return (frame.id & f.mask) == (f.id & f.mask); });
}

FileByteStream::FileByteStream(const std::string& path) : file_(path) {}

ReadResult FileByteStream::do_read(std::span<std::uint8_t> buffer, TimestampNs /*timeout_ns*/) {
  if (!file_.ok()) {
    return {IoStatus::kClosed, 0, 0};
  }
  const std::size_t got = std::fread(buffer.data(), 1, buffer.size(), file_.get());
  if (got > 0) {
    return {IoStatus::kOk, got, 0};
  }
  return {std::ferror(file_.get()) != 0 ? IoStatus::kIoError : IoStatus::kClosed, 0, 0};
}

WriteResult FileByteStream::do_write(std::span<const std::uint8_t> /*bytes*/,
                                     TimestampNs /*timeout_ns*/) {
  return {IoStatus::kInvalidArgument, 0};
}

ByteLogFileStream::ByteLogFileStream(const std::string& path) : file_(path) {
  if (!file_.ok()) {
    error_ = file_.error();
    return;
  }
  fd_ = ::fileno(file_.get());
  struct stat status {};
  std::array<std::uint8_t, 8> magic{};
  const bool read =
      ::fstat(fd_, &status) == 0 && S_ISREG(status.st_mode) &&
      ::pread(fd_, magic.data(), magic.size(), 0) == static_cast<ssize_t>(magic.size());
  size_ = read ? static_cast<std::uint64_t>(status.st_size) : 0;
  offset_ = magic.size();
  constexpr std::size_t kReadAheadBytes = 1 << 16;
  read_ahead_.resize(kReadAheadBytes);
  record_.reserve(4096);
  // A damaged magic in front of records that read well loses nothing else.
  const bool damaged_magic =
      read && !protocol::byte_log::has_magic(magic) && record_starts_at(offset_, std::nullopt);
  if (!read || (!protocol::byte_log::has_magic(magic) && !damaged_magic)) {
    error_ = path + ": not a byte log (it does not start with BMBYTES1)";
    return;
  }
  if (damaged_magic) {
    skipped_places_ = 1;
    skipped_bytes_ = magic.size();
    first_skip_ = protocol::byte_log::ParseError::kBadMagic;
  }
}

bool ByteLogFileStream::read_at(std::uint64_t offset, std::span<std::uint8_t> out) const {
  if (out.size() > read_ahead_.size()) {
    return ::pread(fd_, out.data(), out.size(), static_cast<off_t>(offset)) ==
           static_cast<ssize_t>(out.size());
  }
  if (offset < ahead_from_ || offset + out.size() > ahead_from_ + ahead_bytes_) {
    const ssize_t got =
        ::pread(fd_, read_ahead_.data(), read_ahead_.size(), static_cast<off_t>(offset));
    ahead_from_ = offset;
    ahead_bytes_ = got > 0 ? static_cast<std::size_t>(got) : 0;
    if (ahead_bytes_ < out.size()) {
      return false;
    }
  }
  std::copy_n(read_ahead_.begin() + static_cast<std::ptrdiff_t>(offset - ahead_from_), out.size(),
              out.begin());
  return true;
}

ByteLogFileStream::Header ByteLogFileStream::header_at(std::uint64_t offset) const {
  namespace byte_log = protocol::byte_log;
  Header header;
  std::array<std::uint8_t, byte_log::kRecordHeaderBytes> bytes{};
  if (offset >= size_) {
    header.error = byte_log::ParseError::kEnd;
    return header;
  }
  if (size_ - offset < bytes.size() || !read_at(offset, bytes)) {
    header.error = byte_log::ParseError::kTruncatedHeader;
    return header;
  }
  header.error = byte_log::decode_record_header(bytes, header.fields);
  if (header.error == byte_log::ParseError::kNone &&
      size_ - offset - bytes.size() < header.fields.length) {
    header.error = byte_log::ParseError::kTruncatedData;
  }
  return header;
}

bool ByteLogFileStream::record_starts_at(std::uint64_t offset,
                                         std::optional<TimestampNs> near_ns) const {
  namespace byte_log = protocol::byte_log;
  const Header header = header_at(offset);
  if (header.error != byte_log::ParseError::kNone ||
      (near_ns && !near(*near_ns, header.fields.stamp_ns))) {
    return false;
  }
  const std::uint64_t next = offset + byte_log::kRecordHeaderBytes + header.fields.length;
  if (next == size_) {
    return true;
  }
  // A next record the file's end cuts short still says this one's length was right.
  const Header after = header_at(next);
  if (after.error == byte_log::ParseError::kTruncatedHeader ||
      after.error == byte_log::ParseError::kTruncatedData) {
    return !near_ns;
  }
  return after.error == byte_log::ParseError::kNone &&
         (!near_ns || near(header.fields.stamp_ns, after.fields.stamp_ns));
}

bool ByteLogFileStream::near(TimestampNs before_ns, TimestampNs stamp_ns) noexcept {
  // Where to look again after damage: a device's silence up to a minute, a log written a
  // little out of order.
  constexpr TimestampNs kMaxAfterNs = 60 * kNanosecondsPerSecond;
  constexpr TimestampNs kMaxBeforeNs = kNanosecondsPerSecond;
  return within(before_ns, stamp_ns, kMaxBeforeNs, kMaxAfterNs);
}

std::optional<std::uint64_t> ByteLogFileStream::next_record_start(std::uint64_t from,
                                                                  std::uint64_t until) {
  namespace byte_log = protocol::byte_log;
  // The cheap test first, on the bytes in memory: a direction of 0 or 1 and three zeros.
  constexpr std::size_t kWindowBytes = 1 << 16;
  window_.resize(kWindowBytes);
  while (from < until && from + byte_log::kRecordHeaderBytes <= size_) {
    // The headers of the places before `until`, and no more.
    const auto wanted = static_cast<std::size_t>(
        std::min<std::uint64_t>(window_.size(), until - from + byte_log::kRecordHeaderBytes - 1));
    const ssize_t got = ::pread(fd_, window_.data(), wanted, static_cast<off_t>(from));
    if (got < static_cast<ssize_t>(byte_log::kRecordHeaderBytes)) {
      break;
    }
    const auto usable = static_cast<std::size_t>(got) - byte_log::kRecordHeaderBytes + 1;
    for (std::size_t i = 0; i < usable; ++i) {
      if (window_[i + 12] <= 1 && window_[i + 13] == 0 && window_[i + 14] == 0 &&
          window_[i + 15] == 0 && record_starts_at(from + i, last_good_ns_)) {
        return from + i;
      }
    }
    from += usable;
  }
  return std::nullopt;
}

bool ByteLogFileStream::resynchronise(protocol::byte_log::ParseError why) {
  const std::optional<std::uint64_t> start = next_record_start(offset_ + 1, size_);
  if (!start) {
    ended_ = true;
    return false;
  }
  note_skip(why, *start);
  offset_ = *start;
  return true;
}

void ByteLogFileStream::note_skip(protocol::byte_log::ParseError why, std::uint64_t to) noexcept {
  if (skipped_places_ == 0) {
    first_skip_offset_ = offset_;
    first_skip_ = why;
  }
  ++skipped_places_;
  skipped_bytes_ += to - offset_;
}

protocol::byte_log::ParseError ByteLogFileStream::length_fault(std::uint64_t offset,
                                                               const Header& header,
                                                               std::uint64_t next) {
  namespace byte_log = protocol::byte_log;
  const Header after = header_at(next);
  if (after.error == byte_log::ParseError::kEnd ||
      after.error == byte_log::ParseError::kTruncatedHeader ||
      after.error == byte_log::ParseError::kTruncatedData) {
    return byte_log::ParseError::kNone;
  }
  // A damaged length can land on bytes that read as a header, even on a later record's.
  const TimestampNs after_ns = after.fields.stamp_ns;
  if (after.error == byte_log::ParseError::kNone &&
      (RecordedTimes::follows(header.fields.stamp_ns, after_ns) ||
       (last_good_ns_ && RecordedTimes::follows(*last_good_ns_, after_ns)))) {
    return byte_log::ParseError::kNone;
  }
  // Either the length is wrong, and records start inside the bytes it claims, or the damage
  // (or a device's silence) comes after a whole record.
  if (!next_record_start(offset + 1, next)) {
    return byte_log::ParseError::kNone;
  }
  return after.error != byte_log::ParseError::kNone ? after.error
                                                    : byte_log::ParseError::kBadLength;
}

bool ByteLogFileStream::load_next() {
  namespace byte_log = protocol::byte_log;
  while (!ended_) {
    const Header header = header_at(offset_);
    if (header.error == byte_log::ParseError::kEnd) {
      ended_ = true;
      return false;
    }
    const std::uint64_t next = offset_ + byte_log::kRecordHeaderBytes + header.fields.length;
    const byte_log::ParseError why = header.error != byte_log::ParseError::kNone
                                         ? header.error
                                         : length_fault(offset_, header, next);
    if (why != byte_log::ParseError::kNone) {
      if (resynchronise(why)) {
        continue;
      }
      // Nothing reads well after it: a log cut off ends damaged here; a damaged last record
      // is one more place skipped.
      if (why == byte_log::ParseError::kTruncatedHeader ||
          why == byte_log::ParseError::kTruncatedData) {
        damage_ = why;
        damage_offset_ = offset_;
      } else {
        note_skip(why, size_);
      }
      return false;
    }
    // The times of the records after it, as far as they read well.
    std::array<TimestampNs, RecordedTimes::kConfirming> next_ns{};
    std::size_t known = 0;
    for (std::uint64_t at = next; known < next_ns.size(); ++known) {
      const Header after = header_at(at);
      if (after.error != byte_log::ParseError::kNone) {
        break;
      }
      next_ns[known] = after.fields.stamp_ns;
      at += byte_log::kRecordHeaderBytes + after.fields.length;
    }
    record_.resize(header.fields.length);
    const bool read = read_at(offset_ + byte_log::kRecordHeaderBytes, record_);
    if (!read) {
      damage_ = byte_log::ParseError::kTruncatedData;
      damage_offset_ = offset_;
      ended_ = true;
      return false;
    }
    offset_ = next;
    const std::optional<TimestampNs> stamp_ns =
        times_.judge(header.fields.stamp_ns, std::span<const TimestampNs>(next_ns).first(known));
    if (stamp_ns) {
      last_good_ns_ = *stamp_ns;
    }
    if (stamp_ns && header.fields.direction == byte_log::Direction::kFromDevice &&
        !record_.empty()) {
      stamp_ns_ = *stamp_ns;
      consumed_ = 0;
      return true;
    }
  }
  return false;
}

ReadResult ByteLogFileStream::do_read(std::span<std::uint8_t> buffer, TimestampNs /*timeout_ns*/) {
  if (!ok()) {
    return {IoStatus::kClosed, 0, 0};
  }
  if (consumed_ == record_.size() && !load_next()) {
    return {
        damage_ != protocol::byte_log::ParseError::kNone ? IoStatus::kIoError : IoStatus::kClosed,
        0, 0};
  }
  const std::size_t n = std::min(buffer.size(), record_.size() - consumed_);
  std::copy_n(record_.begin() + static_cast<std::ptrdiff_t>(consumed_), n, buffer.begin());
  consumed_ += n;
  return {IoStatus::kOk, n, stamp_ns_};
}

WriteResult ByteLogFileStream::do_write(std::span<const std::uint8_t> /*bytes*/,
                                        TimestampNs /*timeout_ns*/) {
  return {IoStatus::kInvalidArgument, 0};
}

}  // namespace blockmap::hal::replay
