#include "commands/capture_reader.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <system_error>
#include <utility>

#include "blockmap/hal/protocol/byte_log.hpp"

namespace blockmap::cli {

namespace byte_log = hal::protocol::byte_log;

namespace {

// A raw stream's pieces: big enough that a read is cheap, small beside any budget.
constexpr std::size_t kRawPieceBytes = std::size_t{1} << 16;

}  // namespace

CaptureReader::CaptureReader(std::string path) : path_(std::move(path)) {}

std::string CaptureReader::open() {
  if (path_ == "-") {
    file_ = stdin;
  } else {
    log_.emplace(path_);
    if (!log_->ok()) {
      return log_->error();
    }
    file_ = log_->get();
  }
  buffer_.resize(std::max<std::size_t>(kRawPieceBytes, byte_log::kMaxRecordBytes));
  // The first bytes say which kind of capture it is; a raw one hands them out first.
  std::size_t got = 0;
  if (!read_fully(std::span<std::uint8_t>(buffer_).first(byte_log::kMagic.size()), got)) {
    return damage_;
  }
  timed_ = byte_log::has_magic(std::span<const std::uint8_t>(buffer_).first(got));
  held_ = timed_ ? 0 : got;
  return {};
}

bool CaptureReader::read_fully(std::span<std::uint8_t> out, std::size_t& got) {
  got = std::fread(out.data(), 1, out.size(), file_);
  offset_ += got;
  if (got < out.size() && std::ferror(file_) != 0) {
    damage_ = path_ + ": " + std::generic_category().message(errno);
    return false;
  }
  return true;
}

bool CaptureReader::next(std::span<const std::uint8_t>& bytes, TimestampNs& stamp_ns) {
  if (ended_) {
    return false;
  }
  if (timed_) {
    ended_ = !next_record(bytes, stamp_ns);
    return !ended_;
  }
  std::size_t got = held_;
  if (held_ == 0 && !read_fully(std::span<std::uint8_t>(buffer_).first(kRawPieceBytes), got)) {
    got = 0;
  }
  held_ = 0;
  bytes = std::span<const std::uint8_t>(buffer_).first(got);
  stamp_ns = 0;
  ended_ = got == 0;
  return !ended_;
}

bool CaptureReader::next_record(std::span<const std::uint8_t>& bytes, TimestampNs& stamp_ns) {
  for (;;) {
    const std::uint64_t at = offset_;
    std::array<std::uint8_t, byte_log::kRecordHeaderBytes> header_bytes{};
    std::size_t got = 0;
    if (!read_fully(header_bytes, got) || got == 0) {
      return false;
    }
    byte_log::RecordHeader header;
    byte_log::ParseError error = got < header_bytes.size()
                                     ? byte_log::ParseError::kTruncatedHeader
                                     : byte_log::decode_record_header(header_bytes, header);
    const std::span<std::uint8_t> data = std::span<std::uint8_t>(buffer_).first(
        error == byte_log::ParseError::kNone ? header.length : 0);
    if (error == byte_log::ParseError::kNone && !read_fully(data, got)) {
      return false;
    }
    if (error == byte_log::ParseError::kNone && got < data.size()) {
      error = byte_log::ParseError::kTruncatedData;
    }
    if (error != byte_log::ParseError::kNone) {
      damage_ = path_ + ": byte log record at offset " + std::to_string(at) + ": " +
                byte_log::to_string(error) + "; the records before it were decoded";
      return false;
    }
    if (header.direction == byte_log::Direction::kToDevice) {
      ++host_records_;
      continue;
    }
    bytes = data;
    stamp_ns = header.stamp_ns;
    return true;
  }
}

}  // namespace blockmap::cli
