#include "blockmap/hal/replay/log_ports.hpp"

#include <algorithm>
#include <cerrno>
#include <string_view>
#include <system_error>

#include "blockmap/hal/protocol/candump.hpp"

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

}  // namespace blockmap::hal::replay
