#include "blockmap/hal/replay/log_ports.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <string_view>
#include <system_error>

#include "blockmap/hal/protocol/candump.hpp"
#include "blockmap/hal/protocol/little_endian.hpp"

namespace blockmap::hal::replay {

LogFile::LogFile(const std::string& path) : file_(std::fopen(path.c_str(), "rb")) {
  if (file_ == nullptr) {
    error_ = path + ": " + std::generic_category().message(errno);
  }
}

LogFile::~LogFile() {
  if (file_ != nullptr) {
    static_cast<void>(std::fclose(file_));
  }
}

CandumpFileBus::CandumpFileBus(const std::string& path) : file_(path) {}

CanReceiveResult CandumpFileBus::do_receive(CanFrame& frame, TimestampNs /*timeout_ns*/) {
  if (!file_.ok()) {
    return {IoStatus::kClosed, 0};
  }
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
    return {IoStatus::kOk, record.stamp_ns};
  }
  return {IoStatus::kClosed, 0};
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
  std::array<std::uint8_t, 8> magic{};
  if (std::fread(magic.data(), 1, magic.size(), file_.get()) != magic.size() ||
      !protocol::byte_log::has_magic(magic)) {
    error_ = path + ": not a byte log (it does not start with BMBYTES1)";
    return;
  }
  offset_ = magic.size();
  record_.reserve(protocol::byte_log::kRecordHeaderBytes + 4096);
}

bool ByteLogFileStream::load_next() {
  namespace byte_log = protocol::byte_log;
  while (!ended_) {
    record_.resize(byte_log::kRecordHeaderBytes);
    const std::size_t got = std::fread(record_.data(), 1, record_.size(), file_.get());
    if (got == 0) {
      ended_ = true;  // the end of the log
      return false;
    }
    // Read the record's bytes as its header says (at most kMaxRecordBytes), then let the
    // codec check the whole record.
    std::size_t length = 0;
    if (got == record_.size()) {
      // Four bytes: the value fits any size_t; past the maximum the codec refuses it.
      length = static_cast<std::size_t>(std::min<std::uint64_t>(
          protocol::read_le(std::span<const std::uint8_t>(record_).subspan(8, 4)),
          std::uint64_t{byte_log::kMaxRecordBytes} + 1));
      record_.resize(byte_log::kRecordHeaderBytes + length);
      const std::size_t data =
          std::fread(record_.data() + byte_log::kRecordHeaderBytes, 1, length, file_.get());
      record_.resize(byte_log::kRecordHeaderBytes + data);
    } else {
      record_.resize(got);
    }
    byte_log::Reader reader(record_);
    byte_log::Record record;
    const byte_log::ParseError error = reader.next(record);
    if (error != byte_log::ParseError::kNone) {
      damage_ = error;
      damage_offset_ = offset_;
      ended_ = true;
      return false;
    }
    offset_ += record_.size();
    if (record.header.direction == byte_log::Direction::kFromDevice && record.header.length > 0) {
      stamp_ns_ = record.header.stamp_ns;
      length_ = record.header.length;
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
  if (consumed_ == length_ && !load_next()) {
    return {
        damage_ != protocol::byte_log::ParseError::kNone ? IoStatus::kIoError : IoStatus::kClosed,
        0, 0};
  }
  const std::size_t n = std::min(buffer.size(), length_ - consumed_);
  std::copy_n(record_.begin() +
                  static_cast<std::ptrdiff_t>(protocol::byte_log::kRecordHeaderBytes + consumed_),
              n, buffer.begin());
  consumed_ += n;
  return {IoStatus::kOk, n, stamp_ns_};
}

WriteResult ByteLogFileStream::do_write(std::span<const std::uint8_t> /*bytes*/,
                                        TimestampNs /*timeout_ns*/) {
  return {IoStatus::kInvalidArgument, 0};
}

}  // namespace blockmap::hal::replay
