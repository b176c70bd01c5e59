#include "blockmap/hal/protocol/byte_log.hpp"

#include <algorithm>

#include "blockmap/hal/protocol/little_endian.hpp"

namespace blockmap::hal::protocol::byte_log {

const char* to_string(ParseError error) noexcept {
  switch (error) {
    case ParseError::kNone:
      return "none";
    case ParseError::kEnd:
      return "end";
    case ParseError::kTruncatedHeader:
      return "truncated_header";
    case ParseError::kTruncatedData:
      return "truncated_data";
    case ParseError::kBadDirection:
      return "bad_direction";
    case ParseError::kBadReserved:
      return "bad_reserved";
    case ParseError::kTooLong:
      return "too_long";
    case ParseError::kBadLength:
      return "bad_length";
    case ParseError::kBadMagic:
      return "bad_magic";
  }
  return "unknown";
}

bool has_magic(std::span<const std::uint8_t> file) noexcept {
  return file.size() >= kMagic.size() && std::equal(kMagic.begin(), kMagic.end(), file.begin());
}

void encode_record_header(const RecordHeader& header,
                          std::span<std::uint8_t, kRecordHeaderBytes> out) noexcept {
  write_le(static_cast<std::uint64_t>(header.stamp_ns), out.subspan<0, 8>());
  write_le(header.length, out.subspan<8, 4>());
  out[12] = static_cast<std::uint8_t>(header.direction);
  out[13] = out[14] = out[15] = 0;
}

ParseError decode_record_header(std::span<const std::uint8_t, kRecordHeaderBytes> bytes,
                                RecordHeader& header) noexcept {
  const auto length = static_cast<std::uint32_t>(read_le(bytes.subspan<8, 4>()));
  if (bytes[12] > 1) {
    return ParseError::kBadDirection;
  }
  if (bytes[13] != 0 || bytes[14] != 0 || bytes[15] != 0) {
    return ParseError::kBadReserved;
  }
  if (length > kMaxRecordBytes) {
    return ParseError::kTooLong;
  }
  header.stamp_ns = static_cast<TimestampNs>(read_le(bytes.subspan<0, 8>()));
  header.length = length;
  header.direction = static_cast<Direction>(bytes[12]);
  return ParseError::kNone;
}

ParseError Reader::next(Record& record) noexcept {
  if (rest_.empty()) {
    return ParseError::kEnd;
  }
  if (rest_.size() < kRecordHeaderBytes) {
    return ParseError::kTruncatedHeader;
  }
  if (const ParseError error =
          decode_record_header(rest_.first<kRecordHeaderBytes>(), record.header);
      error != ParseError::kNone) {
    return error;
  }
  if (rest_.size() - kRecordHeaderBytes < record.header.length) {
    return ParseError::kTruncatedData;
  }
  record.bytes = rest_.subspan(kRecordHeaderBytes, record.header.length);
  const std::size_t size = kRecordHeaderBytes + record.header.length;
  rest_ = rest_.subspan(size);
  offset_ += size;
  return ParseError::kNone;
}

}  // namespace blockmap::hal::protocol::byte_log
