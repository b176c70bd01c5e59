// Hokuyo SCIP 2.0 (docs/protocols.md section 4): replies framed by a blank line, one checksum
// character per line, 6-bit characters for values.
#include "blockmap/hal/protocol/hokuyo_scip2.hpp"

#include <charconv>
#include <cstdio>
#include <numbers>

namespace blockmap::hal::protocol::hokuyo_scip2 {
namespace {

constexpr std::size_t kMaxLineBytes = 128;  // parameter lines are the longest; data lines are 65
constexpr std::size_t kDataLineChars = 64;
constexpr std::uint32_t kTimestampWrap = 1U << 24;

// Splits a block of '\n'-terminated lines.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {}
  bool next(std::string_view& line) {
    if (position_ >= text_.size()) return false;
    const std::size_t end = text_.find('\n', position_);
    const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
    line = text_.substr(position_, stop - position_);
    position_ = stop + 1;
    return true;
  }
  [[nodiscard]] std::string_view rest() const {
    return position_ >= text_.size() ? std::string_view() : text_.substr(position_);
  }

 private:
  std::string_view text_;
  std::size_t position_ = 0;
};

// A line that ends in its checksum character; the payload is everything before it.
bool checked(std::string_view line, std::string_view& payload) noexcept {
  if (line.size() < 2) return false;
  payload = line.substr(0, line.size() - 1);
  return checksum(payload) == line.back();
}

bool parse_digits(std::string_view text, std::uint32_t& value) noexcept {
  if (text.empty()) return false;
  for (char c : text) {
    if (c < '0' || c > '9') return false;
  }
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return error == std::errc() && end == text.data() + text.size();
}

// Range code of one value (docs/protocols.md 4.7): below DMIN the value is an error code.
msg::BeamStatus beam_status(std::uint32_t value_mm, const SensorParameters& sensor) noexcept {
  if (value_mm >= sensor.min_range_mm) {
    return value_mm <= sensor.max_range_mm ? msg::BeamStatus::kValid : msg::BeamStatus::kNoReturn;
  }
  if (sensor.max_range_mm > 20000) {  // UTM-30LX class: 1 no object, 2 too near, 3-5 errors
    if (value_mm == 1) return msg::BeamStatus::kNoReturn;
    if (value_mm == 2 || value_mm == 4) return msg::BeamStatus::kTooClose;
    return msg::BeamStatus::kDeviceError;
  }
  // URG-04LX class: 0 and 6 mean "possibly far" (no return); the others are errors.
  return value_mm == 0 || value_mm == 6 ? msg::BeamStatus::kNoReturn
                                        : msg::BeamStatus::kDeviceError;
}

std::size_t append(std::span<char> out, std::size_t at, std::string_view text) noexcept {
  if (at + text.size() > out.size()) return out.size() + 1;  // marks overflow
  for (char c : text) out[at++] = c;
  return at;
}

}  // namespace

const char* to_string(DropReason reason) noexcept {
  switch (reason) {
    case DropReason::kBadChecksum:
      return "bad_checksum";
    case DropReason::kTooLong:
      return "too_long";
    case DropReason::kMalformed:
      return "malformed";
    case DropReason::kBadCharacter:
      return "bad_character";
    case DropReason::kCount:
      break;
  }
  return "?";
}

char checksum(std::string_view payload) noexcept {
  unsigned sum = 0;
  for (char c : payload) sum += static_cast<unsigned char>(c);
  return static_cast<char>((sum & 0x3FU) + 0x30U);
}

std::uint32_t decode_value(std::string_view chars) noexcept {
  std::uint32_t value = 0;
  for (char c : chars)
    value =
        (value << 6) | (static_cast<std::uint32_t>(static_cast<unsigned char>(c) - 0x30U) & 0x3FU);
  return value;
}

Decoder::Decoder(const Config& config) : config_(config), sensor_(config.sensor) {}

Decoder::Step Decoder::push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns) {
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const auto c = static_cast<char>(bytes[i]);
    if (skipping_) {  // until the blank line that ends the broken reply
      const bool blank = c == '\n' && length_ > 0 && buffer_[length_ - 1] == '\n';
      buffer_[0] = c;
      length_ = 1;
      if (blank) {
        skipping_ = false;
        length_ = 0;
        line_start_ = 0;
      }
      continue;
    }
    if (c == '\r') continue;  // tolerated, never part of a line
    if (c != '\n' && (c < 0x20 || c > 0x7E)) return reject(i + 1, DropReason::kBadCharacter);
    if (length_ == 0) {
      if (c == '\n') continue;  // blank lines between replies
      reply_stamp_ns_ = rx_stamp_ns;
    }
    if (length_ == buffer_.size() || (c != '\n' && length_ - line_start_ >= kMaxLineBytes)) {
      return reject(i + 1, DropReason::kTooLong);
    }
    buffer_[length_++] = c;
    if (c != '\n') continue;
    if (length_ - 1 == line_start_) {  // an empty line ends the reply
      return finish_reply(i + 1);
    }
    line_start_ = length_;
  }
  return Step{bytes.size()};
}

Decoder::Step Decoder::reject(std::size_t consumed, DropReason reason) {
  drops_.count(reason);
  // Skip the rest of this reply; a reply that already ended needs no skipping.
  const bool ended = length_ >= 2 && buffer_[length_ - 1] == '\n' && buffer_[length_ - 2] == '\n';
  skipping_ = !ended;
  if (skipping_) {
    buffer_[0] = length_ > 0 ? buffer_[length_ - 1] : '\0';
    length_ = 1;
  } else {
    length_ = 0;
  }
  line_start_ = 0;
  Step step{consumed};
  step.rejected = true;
  step.reason = reason;
  return step;
}

Decoder::Step Decoder::finish_reply(std::size_t consumed) {
  const std::string_view text(buffer_.data(), length_);
  Lines lines(text);
  std::string_view echo;
  std::string_view status_line;
  if (!lines.next(echo) || !lines.next(status_line) || echo.empty()) {
    return reject(consumed, DropReason::kMalformed);
  }
  std::string_view status = status_line;
  if (status_line.size() == 3) {  // SCIP 2.0: two characters and their checksum
    if (!checked(status_line, status)) return reject(consumed, DropReason::kBadChecksum);
  } else if (status_line.size() != 1) {  // SCIP 1.1 replies ("0") carry no checksum
    return reject(consumed, DropReason::kMalformed);
  }
  std::string_view body = lines.rest();
  body = body.substr(0, body.size() - 1);  // the blank line's '\n'
  const bool legacy = status_line.size() == 1;
  const std::string_view command = echo.substr(0, 2);
  bool has_scan = false;
  if (!legacy && (command == "VV" || command == "PP" || command == "II")) {
    if (!read_parameters(body)) return reject(consumed, DropReason::kBadChecksum);
  } else if (!legacy && (echo[0] == 'G' || echo[0] == 'M') && echo.size() >= 12 &&
             (echo[1] == 'D' || echo[1] == 'S') && (status == "00" || status == "99")) {
    if (!read_scan(echo, body, has_scan)) return reject(consumed, drops_reason_);
  }
  reply_ = Reply{echo, status, body, reply_stamp_ns_};
  length_ = 0;
  line_start_ = 0;
  replies_.increment();
  Step step{consumed};
  step.reply = &reply_;
  if (has_scan) {
    scans_.increment();
    step.scan = &scan_;
  }
  return step;
}

bool Decoder::read_parameters(std::string_view body) {
  Lines lines(body);
  std::string_view line;
  SensorParameters updated = sensor_;
  while (lines.next(line)) {
    // NAME:value;c with the checksum over everything before the ';' (docs/protocols.md 4.2).
    const std::size_t semicolon = line.rfind(';');
    const std::size_t colon = line.find(':');
    if (semicolon == std::string_view::npos || semicolon + 2 != line.size() ||
        colon == std::string_view::npos || colon > semicolon ||
        checksum(line.substr(0, semicolon)) != line.back()) {
      return false;
    }
    const std::string_view name = line.substr(0, colon);
    std::uint32_t value = 0;
    if (!parse_digits(line.substr(colon + 1, semicolon - colon - 1), value)) continue;
    if (name == "DMIN") updated.min_range_mm = value;
    if (name == "DMAX") updated.max_range_mm = value;
    if (name == "ARES") updated.steps_per_turn = value;
    if (name == "AMIN") updated.first_step = value;
    if (name == "AMAX") updated.last_step = value;
    if (name == "AFRT") updated.front_step = value;
    if (name == "SCAN") updated.scan_rpm = value;
  }
  if (updated.steps_per_turn > 0 && updated.scan_rpm > 0) {
    sensor_ = updated;
  }
  return true;
}

bool Decoder::read_scan(std::string_view echo, std::string_view body, bool& has_scan) {
  drops_reason_ = DropReason::kMalformed;
  std::uint32_t first_step = 0;
  std::uint32_t last_step = 0;
  std::uint32_t cluster = 0;
  if (!parse_digits(echo.substr(2, 4), first_step) || !parse_digits(echo.substr(6, 4), last_step) ||
      !parse_digits(echo.substr(10, 2), cluster) || last_step < first_step) {
    return false;
  }
  cluster = cluster == 0 ? 1 : cluster;
  Lines lines(body);
  std::string_view line;
  if (!lines.next(line)) {
    has_scan = false;  // an M* command's acceptance: no data yet
    return true;
  }
  std::string_view payload;
  if (line.size() != 5 || !checked(line, payload)) {
    drops_reason_ = line.size() == 5 ? DropReason::kBadChecksum : DropReason::kMalformed;
    return false;
  }
  const std::uint32_t raw_time_ms = decode_value(payload);
  const std::size_t value_chars = echo[1] == 'D' ? 3 : 2;
  const std::size_t expected = (last_step - first_step) / cluster + 1;
  if (expected > msg::kMaxLaserBeams) {
    return false;
  }
  // Values run on across line ends: a three-character value may straddle two lines.
  std::array<char, 4> pending{};
  std::size_t pending_count = 0;
  std::size_t count = 0;
  while (lines.next(line)) {
    if (line.size() > kDataLineChars + 1 || !checked(line, payload)) {
      drops_reason_ =
          line.size() > kDataLineChars + 1 ? DropReason::kMalformed : DropReason::kBadChecksum;
      return false;
    }
    for (char c : payload) {
      pending[pending_count++] = c;
      if (pending_count < value_chars) continue;
      pending_count = 0;
      if (count == expected) return false;
      const std::uint32_t value_mm = decode_value(std::string_view(pending.data(), value_chars));
      scan_.status[count] = beam_status(value_mm, sensor_);
      scan_.ranges_m[count] = static_cast<float>(value_mm) * 0.001F;
      ++count;
    }
  }
  if (count != expected || pending_count != 0) {
    return false;
  }
  // Unwrap the sensor's 24-bit millisecond clock (docs/protocols.md 4.5).
  if (has_time_ && raw_time_ms < last_raw_time_ms_) {
    sensor_time_ms_ += kTimestampWrap;
  }
  sensor_time_ms_ = (sensor_time_ms_ / kTimestampWrap) * kTimestampWrap + raw_time_ms;
  last_raw_time_ms_ = raw_time_ms;
  has_time_ = true;

  const double radians_per_step = 2.0 * std::numbers::pi / sensor_.steps_per_turn;
  const double seconds_per_step =
      60.0 / (static_cast<double>(sensor_.scan_rpm) * sensor_.steps_per_turn);
  scan_.header = msg::Header{reply_stamp_ns_, config_.source_id};
  scan_.start_angle_rad = (static_cast<double>(first_step) - sensor_.front_step) * radians_per_step;
  scan_.angle_increment_rad = cluster * radians_per_step;
  scan_.time_increment_s = cluster * seconds_per_step;
  scan_.scan_period_s = 60.0 / sensor_.scan_rpm;
  scan_.range_min_m = sensor_.min_range_mm * 0.001;
  scan_.range_max_m = sensor_.max_range_mm * 0.001;
  scan_.scan_counter = static_cast<std::uint32_t>(sensor_time_ms_);
  scan_.beam_count = static_cast<std::uint16_t>(count);
  scan_.has_intensities = false;
  has_scan = true;
  return true;
}

std::size_t encode_single_scan_request(std::span<char> out, std::uint32_t first_step,
                                       std::uint32_t last_step, std::uint32_t cluster,
                                       bool three_char) noexcept {
  if (first_step > 9999 || last_step > 9999 || cluster > 99 || out.size() < 14) return 0;
  const int n = std::snprintf(out.data(), out.size(), "G%c%04u%04u%02u\n", three_char ? 'D' : 'S',
                              first_step, last_step, cluster);
  return n > 0 && static_cast<std::size_t>(n) < out.size() ? static_cast<std::size_t>(n) : 0;
}

std::size_t encode_continuous_request(std::span<char> out, std::uint32_t first_step,
                                      std::uint32_t last_step, std::uint32_t cluster,
                                      std::uint32_t skip, std::uint32_t scan_count,
                                      bool three_char) noexcept {
  if (first_step > 9999 || last_step > 9999 || cluster > 99 || skip > 9 || scan_count > 99 ||
      out.size() < 17) {
    return 0;
  }
  const int n =
      std::snprintf(out.data(), out.size(), "M%c%04u%04u%02u%01u%02u\n", three_char ? 'D' : 'S',
                    first_step, last_step, cluster, skip, scan_count);
  return n > 0 && static_cast<std::size_t>(n) < out.size() ? static_cast<std::size_t>(n) : 0;
}

std::size_t encode_scan_reply(std::span<char> out, std::string_view echo, std::string_view status,
                              std::uint32_t time_ms, std::span<const std::uint32_t> values_mm,
                              bool three_char) noexcept {
  if (status.size() != 2) return 0;
  std::size_t at = append(out, 0, echo);
  at = append(out, at, "\n");
  const char status_line[4] = {status[0], status[1], checksum(status), '\n'};
  at = append(out, at, std::string_view(status_line, 4));
  char time_line[6];
  const std::uint32_t raw = time_ms % kTimestampWrap;
  for (std::size_t i = 0; i < 4; ++i) {
    time_line[i] = static_cast<char>(((raw >> (18 - 6 * i)) & 0x3FU) + 0x30U);
  }
  time_line[4] = checksum(std::string_view(time_line, 4));
  time_line[5] = '\n';
  at = append(out, at, std::string_view(time_line, 6));
  // Values as one stream of characters cut into 64-character lines.
  const std::size_t chars_per_value = three_char ? 3 : 2;
  const std::uint32_t limit = three_char ? (1U << 18) - 1 : (1U << 12) - 1;
  char line[kDataLineChars + 2];
  std::size_t in_line = 0;
  for (std::uint32_t value : values_mm) {
    const std::uint32_t clamped = value > limit ? limit : value;
    for (std::size_t i = 0; i < chars_per_value; ++i) {
      line[in_line++] =
          static_cast<char>(((clamped >> (6 * (chars_per_value - 1 - i))) & 0x3FU) + 0x30U);
      if (in_line == kDataLineChars) {
        line[in_line] = checksum(std::string_view(line, in_line));
        line[in_line + 1] = '\n';
        at = append(out, at, std::string_view(line, in_line + 2));
        in_line = 0;
      }
    }
  }
  if (in_line > 0) {
    line[in_line] = checksum(std::string_view(line, in_line));
    line[in_line + 1] = '\n';
    at = append(out, at, std::string_view(line, in_line + 2));
  }
  at = append(out, at, "\n");
  return at <= out.size() ? at : 0;
}

}  // namespace blockmap::hal::protocol::hokuyo_scip2
