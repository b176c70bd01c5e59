#include "blockmap/hal/protocol/candump.hpp"

#include <charconv>
#include <cstdio>
#include <limits>

namespace blockmap::hal::protocol::candump {
namespace {

int hex_digit(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

bool parse_hex(std::string_view text, std::uint32_t& value) noexcept {
  value = 0;
  if (text.empty() || text.size() > 8) {
    return false;
  }
  for (char c : text) {
    const int digit = hex_digit(c);
    if (digit < 0) {
      return false;
    }
    value = value * 16 + static_cast<std::uint32_t>(digit);
  }
  return true;
}

std::string_view trim(std::string_view text) noexcept {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r'))
    text.remove_suffix(1);
  return text;
}

// "seconds.microseconds" -> ns; candump always prints six digits of microseconds.
bool parse_timestamp(std::string_view text, TimestampNs& stamp_ns) noexcept {
  const std::size_t point = text.find('.');
  if (point == std::string_view::npos || point == 0 || text.size() - point - 1 != 6) {
    return false;
  }
  std::int64_t seconds = 0;
  std::int64_t microseconds = 0;
  const auto [end_s, error_s] = std::from_chars(text.data(), text.data() + point, seconds);
  const auto [end_us, error_us] =
      std::from_chars(text.data() + point + 1, text.data() + text.size(), microseconds);
  if (error_s != std::errc() || end_s != text.data() + point || error_us != std::errc() ||
      end_us != text.data() + text.size() || seconds < 0 || microseconds < 0 ||
      seconds > std::numeric_limits<TimestampNs>::max() / kNanosecondsPerSecond - 1) {
    return false;  // found by fuzz_rmp: a huge second count overflowed the ns stamp
  }
  stamp_ns = seconds * kNanosecondsPerSecond + microseconds * 1000;
  return true;
}

ParseError parse_frame(std::string_view text, CanFrame& frame) noexcept {
  const std::size_t hash = text.find('#');
  if (hash == std::string_view::npos) {
    return ParseError::kBadIdentifier;
  }
  const std::string_view id = text.substr(0, hash);
  std::string_view data = text.substr(hash + 1);
  frame = CanFrame{};
  if ((id.size() != 3 && id.size() != 8) || !parse_hex(id, frame.id)) {
    return ParseError::kBadIdentifier;
  }
  frame.extended = id.size() == 8;
  if (frame.extended) {
    frame.error = (frame.id & 0x20000000U) != 0;  // CAN_ERR_FLAG as candump prints it
    frame.id &= 0x1FFFFFFFU;
  } else if (frame.id > 0x7FF) {
    return ParseError::kBadIdentifier;
  }
  if (!data.empty() && data.front() == '#') {
    return ParseError::kBadData;  // CAN FD: not on the RMP's bus
  }
  if (!data.empty() && (data.front() == 'R' || data.front() == 'r')) {
    frame.remote = true;
    return ParseError::kNone;
  }
  if (data.size() % 2 != 0 || data.size() > 16) {
    return ParseError::kBadData;
  }
  for (std::size_t i = 0; i < data.size(); i += 2) {
    const int high = hex_digit(data[i]);
    const int low = hex_digit(data[i + 1]);
    if (high < 0 || low < 0) {
      return ParseError::kBadData;
    }
    frame.data[i / 2] = static_cast<std::uint8_t>(high * 16 + low);
  }
  frame.dlc = static_cast<std::uint8_t>(data.size() / 2);
  return ParseError::kNone;
}

}  // namespace

const char* to_string(ParseError error) noexcept {
  switch (error) {
    case ParseError::kNone:
      return "none";
    case ParseError::kNotAFrame:
      return "not_a_frame";
    case ParseError::kBadTimestamp:
      return "bad_timestamp";
    case ParseError::kBadInterface:
      return "bad_interface";
    case ParseError::kBadIdentifier:
      return "bad_identifier";
    case ParseError::kBadData:
      return "bad_data";
  }
  return "?";
}

ParseError parse_line(std::string_view line, Record& record) noexcept {
  line = trim(line);
  if (line.empty() || line.front() == '#') {
    return ParseError::kNotAFrame;
  }
  const std::size_t close = line.find(')');
  if (line.front() != '(' || close == std::string_view::npos ||
      !parse_timestamp(line.substr(1, close - 1), record.stamp_ns)) {
    return ParseError::kBadTimestamp;
  }
  std::string_view rest = trim(line.substr(close + 1));
  const std::size_t space = rest.find(' ');
  if (space == std::string_view::npos || space == 0 || space >= record.interface.size()) {
    return ParseError::kBadInterface;
  }
  for (char c : rest.substr(0, space)) {
    if (c < 0x21 || c > 0x7E) {  // found by fuzz_rmp: a NUL in the name broke the round trip
      return ParseError::kBadInterface;
    }
  }
  record.interface = {};
  rest.copy(record.interface.data(), space);
  return parse_frame(trim(rest.substr(space + 1)), record.frame);
}

ParseError parse_id_bytes_line(std::string_view line, Record& record) noexcept {
  line = trim(line);
  if (line.empty() || line.front() == '#') {
    return ParseError::kNotAFrame;
  }
  if (line.substr(0, 3) != "id:") {
    return ParseError::kBadIdentifier;
  }
  line.remove_prefix(3);
  const std::size_t space = line.find(' ');
  std::uint32_t id = 0;
  if (space == std::string_view::npos || !parse_hex(line.substr(0, space), id) || id > 0x7FF) {
    return ParseError::kBadIdentifier;
  }
  record.frame = CanFrame{};
  record.frame.id = id;
  std::string_view bytes = trim(line.substr(space + 1));
  while (!bytes.empty()) {
    const std::size_t next = bytes.find(' ');
    const std::string_view token = bytes.substr(0, next);
    std::uint32_t value = 0;
    if (token.size() != 2 || !parse_hex(token, value) || record.frame.dlc == 8) {
      return ParseError::kBadData;
    }
    record.frame.data[record.frame.dlc++] = static_cast<std::uint8_t>(value);
    bytes = next == std::string_view::npos ? std::string_view() : trim(bytes.substr(next + 1));
  }
  return ParseError::kNone;
}

std::size_t format_line(const Record& record, std::span<char> out) noexcept {
  const CanFrame& f = record.frame;
  const long long seconds = record.stamp_ns / kNanosecondsPerSecond;
  const long long microseconds = record.stamp_ns % kNanosecondsPerSecond / 1000;
  int written =
      f.extended || f.error
          ? std::snprintf(out.data(), out.size(), "(%lld.%06lld) %s %08X#", seconds, microseconds,
                          record.interface.data(),
                          static_cast<unsigned>(f.id | (f.error ? 0x20000000U : 0U)))
          : std::snprintf(out.data(), out.size(), "(%lld.%06lld) %s %03X#", seconds, microseconds,
                          record.interface.data(), static_cast<unsigned>(f.id));
  if (written < 0 || static_cast<std::size_t>(written) >= out.size()) {
    return 0;
  }
  auto length = static_cast<std::size_t>(written);
  const std::size_t needed = f.remote ? 1 : 2 * std::size_t{f.dlc};
  if (length + needed >= out.size()) {
    return 0;
  }
  if (f.remote) {
    out[length++] = 'R';
  } else {
    static constexpr char kHex[] = "0123456789ABCDEF";
    for (std::size_t i = 0; i < f.dlc && i < f.data.size(); ++i) {
      out[length++] = kHex[f.data[i] >> 4];
      out[length++] = kHex[f.data[i] & 0x0F];
    }
  }
  out[length] = '\0';
  return length;
}

}  // namespace blockmap::hal::protocol::candump
