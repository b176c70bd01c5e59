// SICK CoLa codec (docs/protocols.md section 3). One framing state machine over one telegram
// buffer; one LMDscandata parser templated on a field reader per dialect (CoLa B big-endian
// binary, CoLa A hex tokens), so that the hot loops are inlined with no virtual calls; one writer
// for both dialects behind the encoders.
#include "blockmap/hal/protocol/sick_cola.hpp"
#include "blockmap/core/angles.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>

#include "blockmap/core/check.hpp"

namespace blockmap::hal::protocol::sick_cola {
namespace {

constexpr std::uint8_t kStx = 0x02;
constexpr std::uint8_t kEtx = 0x03;
constexpr std::size_t kColaBHeaderBytes = 8;  // 02 02 02 02 + u32 BE length (docs/protocols.md 3.2)
constexpr std::size_t kColaBOverheadBytes = 9;  // the header and the XOR byte after the body
constexpr std::size_t kMaxColaBBodyBytes = 0x7FFFFFFF;  // what a u32 length holds on every target
constexpr double kDegreesPerAngleUnit = 1e-4;  // LMDscandata angles are 1/10000 degree (3.4)
constexpr double kMetresPerMillimetre = 1e-3;
// SICK numbers its beams with 90 degrees straight ahead: a TiM5xx/7xx or LMS1xx scans -45..225,
// an LMS5xx -5..185, counter-clockwise seen from above. msg::LaserScan wants x forward, y left,
// counter-clockwise positive, so scanner-frame angle = SICK angle - 90 degrees, the conversion of
// sick_tim (docs/protocols.md 3.4 [S11]) that the S14 start-up log confirms (-45..225 is -135..+135
// in the robot frame). Beam order and direction stay as sent; no mirroring.
constexpr double kScannerFrameMinusSickDeg = -90.0;

std::uint16_t be16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>((static_cast<unsigned>(p[0]) << 8U) | p[1]);
}

std::uint32_t be32(const std::uint8_t* p) noexcept {
  return (static_cast<std::uint32_t>(p[0]) << 24U) | (static_cast<std::uint32_t>(p[1]) << 16U) |
         (static_cast<std::uint32_t>(p[2]) << 8U) | p[3];
}

// Hex digit values, -1 for anything else: one load per character in the CoLa A hot loop.
constexpr std::array<std::int8_t, 256> kHexDigit = [] {
  std::array<std::int8_t, 256> table{};
  table.fill(-1);
  for (std::size_t d = 0; d < 10; ++d) {
    table['0' + d] = static_cast<std::int8_t>(d);
  }
  for (std::size_t d = 0; d < 6; ++d) {
    table['A' + d] = static_cast<std::int8_t>(10 + d);
    table['a' + d] = static_cast<std::int8_t>(10 + d);
  }
  return table;
}();

int hex_digit(char c) noexcept {
  return kHexDigit[static_cast<unsigned char>(c)];
}

bool is_letter(std::uint8_t c) noexcept {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
}

// CoLa A carries printable ASCII only; anything else ends (ETX) or breaks (STX, noise) a telegram.
bool is_cola_a_text(std::uint8_t c) noexcept {
  return c >= 0x20 && c <= 0x7E;
}

// Index of the first byte that is not CoLa A text, or bytes.size().
std::size_t find_cola_a_stop(std::span<const std::uint8_t> bytes) noexcept {
  std::size_t i = 0;
  while (i < bytes.size() && is_cola_a_text(bytes[i])) {
    ++i;
  }
  return i;
}

std::string_view text_of(std::span<const std::uint8_t> bytes) noexcept {
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

// --- field readers: the same calls read a CoLa B body and a CoLa A token list

class BinaryReader {
 public:
  explicit BinaryReader(std::span<const std::uint8_t> data) noexcept : data_(data) {}

  bool u8(std::uint8_t& value) noexcept {
    if (!has(1)) return false;
    value = data_[position_++];
    return true;
  }
  bool u16(std::uint16_t& value) noexcept {
    if (!has(2)) return false;
    value = be16(data_.data() + position_);
    position_ += 2;
    return true;
  }
  bool u32(std::uint32_t& value) noexcept {
    if (!has(4)) return false;
    value = be32(data_.data() + position_);
    position_ += 4;
    return true;
  }
  bool i32(std::int32_t& value) noexcept {
    std::uint32_t bits = 0;
    if (!u32(bits)) return false;
    value = static_cast<std::int32_t>(bits);  // two's complement (C++20)
    return true;
  }
  bool f32(float& value) noexcept {
    std::uint32_t bits = 0;
    if (!u32(bits)) return false;
    value = std::bit_cast<float>(bits);
    return true;
  }
  // A channel name: 5 characters, no length (docs/protocols.md 3.4).
  bool name(std::array<char, 6>& out) noexcept {
    if (!has(5)) return false;
    for (std::size_t i = 0; i < 5; ++i) {
      out[i] = static_cast<char>(data_[position_ + i]);
    }
    out[5] = '\0';
    position_ += 5;
    return true;
  }
  // `count` values of `bits` (16 or 8) bits, each handed to sink(index, value).
  template <typename Sink>
  bool values(std::size_t count, std::uint8_t bits, Sink&& sink) noexcept {
    const std::size_t width = bits == 16 ? 2 : 1;
    if (!has(count * width)) return false;
    const std::uint8_t* p = data_.data() + position_;
    if (width == 2) {
      for (std::size_t i = 0; i < count; ++i) {
        sink(i, std::uint32_t{be16(p + 2 * i)});
      }
    } else {
      for (std::size_t i = 0; i < count; ++i) {
        sink(i, std::uint32_t{p[i]});
      }
    }
    position_ += count * width;
    return true;
  }

 private:
  [[nodiscard]] bool has(std::size_t bytes) const noexcept {
    return data_.size() - position_ >= bytes;
  }

  std::span<const std::uint8_t> data_;
  std::size_t position_ = 0;
};

// CoLa A fields are tokens separated by a space: unsigned numbers in upper-case hex without
// leading zeros, s32 as two's complement hex ("FFF92230" = -450000), floats as their IEEE-754
// bits in hex, some configuration values as signed decimal with '+' or '-' (docs/protocols.md 3.2).
class AsciiReader {
 public:
  explicit AsciiReader(std::string_view text) noexcept : text_(text) {}

  bool u8(std::uint8_t& value) noexcept { return unsigned_field(0xFFU, value); }
  bool u16(std::uint16_t& value) noexcept { return unsigned_field(0xFFFFU, value); }
  bool u32(std::uint32_t& value) noexcept { return unsigned_field(0xFFFFFFFFU, value); }
  bool i32(std::int32_t& value) noexcept {
    std::string_view token;
    if (!next(token)) return false;
    if (token.front() == '+' || token.front() == '-') {
      return decimal(token, value);
    }
    std::uint32_t bits = 0;
    if (!hex(token, bits)) return false;
    value = static_cast<std::int32_t>(bits);
    return true;
  }
  bool f32(float& value) noexcept {
    std::string_view token;
    std::uint32_t bits = 0;
    if (!next(token) || !hex(token, bits)) return false;
    value = std::bit_cast<float>(bits);
    return true;
  }
  bool name(std::array<char, 6>& out) noexcept {
    std::string_view token;
    if (!next(token) || token.size() > 5) return false;
    out = {};
    std::copy(token.begin(), token.end(), out.begin());
    return true;
  }
  template <typename Sink>
  bool values(std::size_t count, std::uint8_t bits, Sink&& sink) noexcept {
    const std::uint32_t max = bits == 16 ? 0xFFFFU : 0xFFU;
    for (std::size_t i = 0; i < count; ++i) {
      std::uint32_t value = 0;
      if (!unsigned_field(max, value)) return false;
      sink(i, value);
    }
    return true;
  }

 private:
  bool next(std::string_view& token) noexcept {
    while (position_ < text_.size() && text_[position_] == ' ') {
      ++position_;
    }
    const std::size_t end = std::min(text_.find(' ', position_), text_.size());
    token = text_.substr(position_, end - position_);
    position_ = end;
    return !token.empty();
  }
  static bool hex(std::string_view token, std::uint32_t& value) noexcept {
    if (token.empty() || token.size() > 8) return false;
    std::uint32_t result = 0;
    for (char c : token) {
      const int digit = hex_digit(c);
      if (digit < 0) return false;
      result = (result << 4U) | static_cast<std::uint32_t>(digit);
    }
    value = result;
    return true;
  }
  template <typename Integer>
  static bool decimal(std::string_view token, Integer& value) noexcept {
    if (token.front() == '+') token.remove_prefix(1);
    const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    return error == std::errc() && end == token.data() + token.size() && !token.empty();
  }
  // The hot path: one pass over a hex token, with the rare "+decimal" form handed on.
  template <typename Unsigned>
  bool unsigned_field(std::uint32_t max, Unsigned& value) noexcept {
    while (position_ < text_.size() && text_[position_] == ' ') {
      ++position_;
    }
    if (position_ < text_.size() && text_[position_] == '+') {
      std::string_view token;
      std::uint32_t parsed = 0;
      if (!next(token) || !decimal(token, parsed) || parsed > max) return false;
      value = static_cast<Unsigned>(parsed);
      return true;
    }
    const std::size_t first = position_;
    std::uint32_t parsed = 0;
    while (position_ < text_.size() && text_[position_] != ' ') {
      const int digit = hex_digit(text_[position_]);
      if (digit < 0) return false;
      parsed = (parsed << 4U) | static_cast<std::uint32_t>(digit);
      ++position_;
    }
    const std::size_t digits = position_ - first;
    if (digits == 0 || digits > 8 || parsed > max) return false;
    value = static_cast<Unsigned>(parsed);
    return true;
  }

  std::string_view text_;
  std::size_t position_ = 0;
};

// --- LMDscandata (docs/protocols.md 3.4): the same field order in both dialects

template <typename Reader>
class ScanParser {
 public:
  ScanParser(Reader& reader, ScanInfo& info, msg::LaserScan& scan) noexcept
      : r_(reader), info_(info), scan_(scan) {}

  std::optional<DropReason> parse() noexcept {
    info_ = ScanInfo{};
    if (!header() || !encoders()) return DropReason::kMalformed;
    if (const auto failure = channel_blocks(16, info_.channel16_count)) return failure;
    if (const auto failure = channel_blocks(8, info_.channel8_count)) return failure;
    if (!has_distance_ || (info_.has_rssi && info_.rssi.count != info_.distance.count)) {
      return DropReason::kMalformed;
    }
    trailer();
    return std::nullopt;
  }

 private:
  bool header() noexcept {
    ScanInfo& i = info_;
    return r_.u16(i.version) && r_.u16(i.device_number) && r_.u32(i.serial_number) &&
           r_.u8(i.device_status[0]) && r_.u8(i.device_status[1]) && r_.u16(i.telegram_counter) &&
           r_.u16(i.scan_counter) && r_.u32(i.time_since_startup_us) &&
           r_.u32(i.time_of_transmission_us) && r_.u8(i.digital_inputs[0]) &&
           r_.u8(i.digital_inputs[1]) && r_.u8(i.digital_outputs[0]) &&
           r_.u8(i.digital_outputs[1]) && r_.u16(i.reserved) && r_.u32(i.scan_frequency_centihz) &&
           r_.u32(i.measurement_frequency_hectohz);
  }

  // u16 count, then per encoder u32 position and u16 speed; the first one is kept.
  bool encoders() noexcept {
    if (!r_.u16(info_.encoder_count)) return false;
    for (std::size_t e = 0; e < info_.encoder_count; ++e) {
      std::uint32_t position = 0;
      std::uint16_t speed = 0;
      if (!r_.u32(position) || !r_.u16(speed)) return false;
      if (e == 0) {
        info_.encoder_position = position;
        info_.encoder_speed = speed;
      }
    }
    return true;
  }

  std::optional<DropReason> channel_blocks(std::uint8_t bits, std::uint16_t& count) noexcept {
    if (!r_.u16(count)) return DropReason::kMalformed;
    for (std::size_t c = 0; c < count; ++c) {
      if (const auto failure = channel(bits)) return failure;
    }
    return std::nullopt;
  }

  // One block: name, scale, offset, start angle, step, count, values. DIST1 and RSSI1 are kept
  // (whichever width they come in); other channels (DIST2.., RSSI2.., ANGL, ...) are skipped.
  std::optional<DropReason> channel(std::uint8_t bits) noexcept {
    ScanChannel block;
    block.bits = bits;
    if (!r_.name(block.name) || !r_.f32(block.scale_factor) || !r_.f32(block.scale_offset) ||
        !r_.i32(block.start_angle_1e4deg) || !r_.u16(block.step_1e4deg) || !r_.u16(block.count)) {
      return DropReason::kMalformed;
    }
    const std::string_view name(block.name.data());
    const bool is_distance = !has_distance_ && name == "DIST1";
    const bool is_rssi = !info_.has_rssi && name == "RSSI1";
    if ((is_distance || is_rssi) && block.count > msg::kMaxLaserBeams) {
      return DropReason::kTooManyBeams;
    }
    bool ok = false;
    if (is_distance) {
      ok = distances(block);
      info_.distance = block;
      has_distance_ = true;
    } else if (is_rssi) {
      // Intensities stay in device units: the RSSI scale (1.0 in every capture) is kept in
      // ScanInfo for whoever needs calibrated values.
      ok = r_.values(block.count, bits, [this](std::size_t i, std::uint32_t raw) {
        scan_.intensities[i] = static_cast<float>(raw);
      });
      info_.rssi = block;
      info_.has_rssi = true;
    } else {
      ok = r_.values(block.count, bits, [](std::size_t, std::uint32_t) {});
    }
    return ok ? std::nullopt : std::optional<DropReason>(DropReason::kMalformed);
  }

  // Range = value x scale x 0.001 + offset, in metres (docs/protocols.md 3.4 [S14]); 0 = no echo
  // [S11]. Every capture uses scale 1 and offset 0 (3.6 [UNVERIFIED] for other scales).
  bool distances(const ScanChannel& block) noexcept {
    const double metres_per_unit = static_cast<double>(block.scale_factor) * kMetresPerMillimetre;
    const auto offset_m = static_cast<double>(block.scale_offset);
    return r_.values(block.count, block.bits, [&](std::size_t i, std::uint32_t raw) {
      scan_.ranges_m[i] = static_cast<float>(static_cast<double>(raw) * metres_per_unit + offset_m);
      scan_.status[i] = raw == 0 ? msg::BeamStatus::kNoReturn : msg::BeamStatus::kValid;
    });
  }

  // After the channels: u16 flags for position, name, comment and time, each followed by its
  // block when set. docs/protocols.md 3.4 gives the time block only, so the time is read when the
  // blocks before it are absent (as in every capture) and is left out otherwise. A short or odd
  // trailer does not make the scan invalid: the scan itself is complete by now.
  void trailer() noexcept {
    std::uint16_t position = 0;
    std::uint16_t device_name = 0;
    std::uint16_t comment = 0;
    std::uint16_t time = 0;
    if (!r_.u16(position) || position != 0 || !r_.u16(device_name) || device_name != 0 ||
        !r_.u16(comment) || comment != 0 || !r_.u16(time) || time != 1) {
      return;
    }
    DeviceTime t;
    if (r_.u16(t.year) && r_.u8(t.month) && r_.u8(t.day) && r_.u8(t.hour) && r_.u8(t.minute) &&
        r_.u8(t.second) && r_.u32(t.microsecond)) {
      info_.device_time = t;
      info_.has_device_time = true;
    }
  }

  Reader& r_;
  ScanInfo& info_;
  msg::LaserScan& scan_;
  bool has_distance_ = false;
};

// The LaserScan fields that come from the whole telegram rather than from one beam.
void fill_scan(const ScanInfo& info, const Telegram& telegram, const Config& config,
               msg::LaserScan& scan) noexcept {
  const ScanChannel& d = info.distance;
  scan.header = msg::Header{telegram.stamp_ns, config.source_id};
  scan.start_angle_rad = (static_cast<double>(d.start_angle_1e4deg) * kDegreesPerAngleUnit +
                          kScannerFrameMinusSickDeg) *
                         kRadiansPerDegree;
  scan.angle_increment_rad =
      static_cast<double>(d.step_1e4deg) * kDegreesPerAngleUnit * kRadiansPerDegree;
  // Scan frequency in 1/100 Hz, measurement frequency in 100 Hz (docs/protocols.md 3.4, sick_tim's
  // "scan time = 100/freq; time increment = 1/(measfreq*100)" [S11]).
  scan.scan_period_s = info.scan_frequency_centihz == 0
                           ? 0.0
                           : 100.0 / static_cast<double>(info.scan_frequency_centihz);
  scan.time_increment_s =
      info.measurement_frequency_hectohz == 0
          ? 0.0
          : 1.0 / (static_cast<double>(info.measurement_frequency_hectohz) * 100.0);
  scan.range_min_m = config.range_min_m;
  scan.range_max_m = config.range_max_m;
  scan.scan_counter = info.scan_counter;
  scan.beam_count = d.count;
  scan.has_intensities = info.has_rssi;
}

// Beam status beyond "0 = no echo": RSSI 0 (Config::rssi_zero_is_no_return) and the minimum range.
void classify_beams(const Config& config, msg::LaserScan& scan) noexcept {
  const std::size_t n = scan.beam_count;
  if (!scan.has_intensities) {
    std::fill_n(scan.intensities.begin(), n, 0.0F);
  } else if (config.rssi_zero_is_no_return) {
    for (std::size_t i = 0; i < n; ++i) {
      if (scan.intensities[i] == 0.0F) {
        scan.status[i] = msg::BeamStatus::kNoReturn;
      }
    }
  }
  if (config.range_min_m > 0.0) {
    const auto range_min_m = static_cast<float>(config.range_min_m);
    for (std::size_t i = 0; i < n; ++i) {
      if (scan.status[i] == msg::BeamStatus::kValid && scan.ranges_m[i] < range_min_m) {
        scan.status[i] = msg::BeamStatus::kTooClose;
      }
    }
  }
}

// "type command payload": a 3-letter type starting with 's', then (after one space) the command
// name up to the next space. A type not followed by a space (CoLa B "sFA" + u16 error code) has no
// command; its payload starts right after the type.
bool split_telegram(std::span<const std::uint8_t> body, Telegram& telegram) noexcept {
  if (body.size() < 3 || body[0] != 's' || !is_letter(body[1]) || !is_letter(body[2])) {
    return false;
  }
  telegram.type = text_of(body.first(3));
  telegram.command = {};
  telegram.payload = body.subspan(3);
  if (body.size() == 3 || body[3] != ' ') {
    return true;
  }
  const std::span<const std::uint8_t> rest = body.subspan(4);
  std::size_t end = 0;
  while (end < rest.size() && rest[end] != ' ') {
    if (rest[end] <= 0x20 || rest[end] > 0x7E) return false;
    ++end;
  }
  telegram.command = text_of(rest.first(end));
  telegram.payload = rest.subspan(std::min(end + 1, rest.size()));
  return true;
}

bool is_scan_telegram(const Telegram& telegram) noexcept {
  return (telegram.type == "sSN" || telegram.type == "sRA") && telegram.command == "LMDscandata";
}

std::uint32_t rounded_u32(double value, double max) noexcept {
  if (!(value > 0.0)) return 0;  // also NaN
  return static_cast<std::uint32_t>(std::lround(std::min(value, max)));
}

}  // namespace

const char* to_string(Dialect dialect) noexcept {
  switch (dialect) {
    case Dialect::kColaA:
      return "cola_a";
    case Dialect::kColaB:
      return "cola_b";
  }
  return "?";
}

const char* to_string(DropReason reason) noexcept {
  switch (reason) {
    case DropReason::kGarbage:
      return "garbage";
    case DropReason::kBadLength:
      return "bad_length";
    case DropReason::kBadChecksum:
      return "bad_checksum";
    case DropReason::kTruncated:
      return "truncated";
    case DropReason::kBadCharacter:
      return "bad_character";
    case DropReason::kTooLong:
      return "too_long";
    case DropReason::kMalformed:
      return "malformed";
    case DropReason::kTooManyBeams:
      return "too_many_beams";
    case DropReason::kCount:
      break;
  }
  return "?";
}

std::uint8_t checksum(std::span<const std::uint8_t> body) noexcept {
  std::uint8_t sum = 0;
  for (std::uint8_t byte : body) {
    sum = static_cast<std::uint8_t>(sum ^ byte);
  }
  return sum;
}

// --- decoder

Decoder::Decoder(std::span<std::uint8_t> telegram_storage, const Config& config)
    : config_(config),
      framing_(config.framing),
      buffer_(telegram_storage.data()),
      capacity_(telegram_storage.size()) {
  BLOCKMAP_CHECK_MSG(capacity_ >= kMinTelegramCapacityBytes,
                     "a CoLa telegram buffer needs at least 64 bytes");
}

Decoder::Decoder(Arena& arena, const Config& config)
    : Decoder(arena.allocate_array<std::uint8_t>(config.telegram_capacity_bytes,
                                                 "sick_cola telegram buffer"),
              config) {}

Decoder::Step Decoder::push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns) {
  return run(bytes, rx_stamp_ns, false);
}

Decoder::Step Decoder::flush() {
  return run({}, 0, true);
}

Decoder::Step Decoder::run(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns,
                           bool end_of_input) {
  if (delivered_ > 0) {  // the caller is done with the telegram delivered last time
    drop_front(delivered_);
    delivered_ = 0;
  }
  std::size_t used = 0;
  for (;;) {
    if (length_ == 0) {
      used += skip_garbage(bytes.subspan(used));
    }
    const Examination next =
        length_ == 0 ? Examination{Outcome::kNeedMore, 1, DropReason::kGarbage} : examine();
    switch (next.outcome) {
      case Outcome::kNeedMore:
        if (used == bytes.size()) {
          return end_of_input && length_ > 0 ? reject(used, DropReason::kTruncated, next_start(1))
                                             : Step{used};
        }
        used += append(bytes.subspan(used), next.bytes, rx_stamp_ns);
        break;
      case Outcome::kGarbage:
        drops_.count(DropReason::kGarbage, next.bytes);
        dropped_bytes_.increment(next.bytes);
        drop_front(next.bytes);
        break;
      case Outcome::kReject:
        return reject(used, next.reason, next.bytes);
      case Outcome::kComplete:
        return deliver(used, next.bytes);
    }
  }
}

std::size_t Decoder::skip_garbage(std::span<const std::uint8_t> bytes) noexcept {
  if (bytes.empty()) {
    return 0;
  }
  const void* stx = std::memchr(bytes.data(), kStx, bytes.size());
  const std::size_t skipped =
      stx == nullptr
          ? bytes.size()
          : static_cast<std::size_t>(static_cast<const std::uint8_t*>(stx) - bytes.data());
  drops_.count(DropReason::kGarbage, skipped);
  dropped_bytes_.increment(skipped);
  stream_offset_ += skipped;
  return skipped;
}

// Copies what the examination asked for: up to `wanted` bytes in all (CoLa B, or the byte that
// tells the dialect), or (wanted == 0, CoLa A) up to and including the next stop byte.
std::size_t Decoder::append(std::span<const std::uint8_t> bytes, std::size_t wanted,
                            TimestampNs rx_stamp_ns) noexcept {
  std::size_t count = 0;
  if (wanted > 0) {
    count = std::min(wanted - length_, bytes.size());
  } else {
    const std::size_t limit = std::min(capacity_ - length_, bytes.size());
    const std::size_t stop = find_cola_a_stop(bytes.first(limit));
    count = stop < limit ? stop + 1 : limit;
    scanned_ = length_ + stop;  // examine_cola_a() need not search these text bytes again
  }
  // A new receive stamp from here on. When the marks are full (more than kStampMarks chunks in
  // one telegram), later bytes keep the last stamp recorded: earlier than the truth, and only
  // for telegrams found again inside rejected bytes.
  if ((mark_count_ == 0 || marks_[mark_count_ - 1].stamp_ns != rx_stamp_ns) &&
      mark_count_ < kStampMarks) {
    marks_[mark_count_++] = StampMark{stream_offset_, rx_stamp_ns};
  }
  std::memcpy(buffer_ + length_, bytes.data(), count);
  length_ += count;
  stream_offset_ += count;
  return count;
}

void Decoder::drop_front(std::size_t bytes) noexcept {
  scanned_ = 1;
  if (bytes >= length_) {
    length_ = 0;
    mark_count_ = 0;
    return;
  }
  std::memmove(buffer_, buffer_ + bytes, length_ - bytes);
  length_ -= bytes;
  // Keep the latest mark at or before the new first byte, and every later one.
  const std::uint64_t start = candidate_offset();
  std::size_t first = 0;
  while (first + 1 < mark_count_ && marks_[first + 1].offset <= start) {
    ++first;
  }
  std::copy(marks_.begin() + static_cast<std::ptrdiff_t>(first),
            marks_.begin() + static_cast<std::ptrdiff_t>(mark_count_), marks_.begin());
  mark_count_ -= first;
  marks_[0].offset = start;
}

TimestampNs Decoder::candidate_stamp() const noexcept {
  return mark_count_ == 0 ? 0 : marks_[0].stamp_ns;
}

Dialect Decoder::candidate_dialect() const noexcept {
  if (framing_ == Framing::kColaA) return Dialect::kColaA;
  if (framing_ == Framing::kColaB) return Dialect::kColaB;
  return length_ > 1 && buffer_[1] == kStx ? Dialect::kColaB : Dialect::kColaA;
}

// Could a telegram begin at buffer_[index] (an STX), judging by the bytes held after it?
bool Decoder::possible_start(std::size_t index) const noexcept {
  if (framing_ == Framing::kColaA || index + 1 >= length_) {
    return true;
  }
  if (framing_ == Framing::kDetect && buffer_[index + 1] == 's') {
    return true;
  }
  const std::size_t end = std::min(length_, index + 4);
  for (std::size_t k = index + 1; k < end; ++k) {
    if (buffer_[k] != kStx) return false;
  }
  return true;
}

// The first possible start at or after `from`, or length_. This is how a telegram that began
// inside rejected bytes (a false `02 02 02 02` in noise, a cut-off telegram) is found again.
std::size_t Decoder::next_start(std::size_t from) const noexcept {
  std::size_t index = from;
  while (index < length_) {
    const void* stx = std::memchr(buffer_ + index, kStx, length_ - index);
    if (stx == nullptr) {
      return length_;
    }
    index = static_cast<std::size_t>(static_cast<const std::uint8_t*>(stx) - buffer_);
    if (possible_start(index)) {
      return index;
    }
    ++index;
  }
  return length_;
}

Decoder::Examination Decoder::examine() noexcept {
  if (buffer_[0] != kStx) {  // bytes left after a delivered telegram, before the next STX
    return {Outcome::kGarbage, next_start(1), DropReason::kGarbage};
  }
  if (framing_ == Framing::kDetect) {
    if (length_ < 2) {
      return {Outcome::kNeedMore, 2, DropReason::kGarbage};
    }
    if (buffer_[1] != kStx && buffer_[1] != 's') {
      return {Outcome::kGarbage, next_start(1), DropReason::kGarbage};
    }
  }
  return candidate_dialect() == Dialect::kColaB ? examine_cola_b() : examine_cola_a();
}

// `02 02 02 02 | u32 BE length | body | XOR(body)` (docs/protocols.md 3.2 [solid]).
Decoder::Examination Decoder::examine_cola_b() noexcept {
  const std::size_t pattern_bytes = std::min<std::size_t>(length_, 4);
  for (std::size_t k = 1; k < pattern_bytes; ++k) {
    if (buffer_[k] != kStx) {
      return {Outcome::kGarbage, next_start(1), DropReason::kGarbage};
    }
  }
  if (length_ < kColaBHeaderBytes) {
    return {Outcome::kNeedMore, kColaBHeaderBytes, DropReason::kGarbage};
  }
  const std::uint32_t body_bytes = be32(buffer_ + 4);
  if (body_bytes == 0 || body_bytes > capacity_ - kColaBOverheadBytes) {
    return {Outcome::kReject, next_start(1), DropReason::kBadLength};
  }
  const std::size_t frame_bytes = kColaBOverheadBytes + body_bytes;
  if (length_ < frame_bytes) {
    return {Outcome::kNeedMore, frame_bytes, DropReason::kGarbage};
  }
  const std::span<const std::uint8_t> body(buffer_ + kColaBHeaderBytes, body_bytes);
  if (checksum(body) != buffer_[frame_bytes - 1]) {
    return {Outcome::kReject, next_start(1), DropReason::kBadChecksum};
  }
  return {Outcome::kComplete, frame_bytes, DropReason::kGarbage};
}

// `02 | printable ASCII | 03`, no checksum (docs/protocols.md 3.2 [solid]). A CoLa A telegram holds
// no STX, so a rejected one never hides the start of the next: nothing is searched again.
Decoder::Examination Decoder::examine_cola_a() noexcept {
  const std::size_t stop = scanned_ + find_cola_a_stop(std::span<const std::uint8_t>(
                                          buffer_ + scanned_, length_ - scanned_));
  if (stop == length_) {
    scanned_ = length_;
    if (length_ == capacity_) {
      return {Outcome::kReject, length_, DropReason::kTooLong};
    }
    return {Outcome::kNeedMore, 0, DropReason::kGarbage};
  }
  const std::uint8_t byte = buffer_[stop];
  if (byte == kEtx) {
    return {Outcome::kComplete, stop + 1, DropReason::kGarbage};
  }
  if (stop == 1) {  // an STX straight before another stop byte: noise, not a telegram
    return {Outcome::kGarbage, byte == kStx ? std::size_t{1} : std::size_t{2},
            DropReason::kGarbage};
  }
  if (byte == kStx) {
    return {Outcome::kReject, stop, DropReason::kTruncated};
  }
  return {Outcome::kReject, stop + 1, DropReason::kBadCharacter};
}

Decoder::Step Decoder::reject(std::size_t consumed, DropReason reason, std::size_t drop) noexcept {
  drops_.count(reason);
  dropped_bytes_.increment(drop);
  Step step{consumed};
  step.rejected = true;
  step.reason = reason;
  step.start_offset = candidate_offset();
  drop_front(drop);
  return step;
}

Decoder::Step Decoder::deliver(std::size_t consumed, std::size_t frame_bytes) noexcept {
  const Dialect dialect = candidate_dialect();
  const std::span<const std::uint8_t> body =
      dialect == Dialect::kColaB ? std::span<const std::uint8_t>(buffer_ + kColaBHeaderBytes,
                                                                 frame_bytes - kColaBOverheadBytes)
                                 : std::span<const std::uint8_t>(buffer_ + 1, frame_bytes - 2);
  Telegram& telegram = telegram_;
  if (!split_telegram(body, telegram)) {
    // Not a CoLa telegram. For CoLa B, noise that matched the XOR (1 in 256): a real telegram
    // may begin inside it, so it is searched again.
    return reject(consumed, DropReason::kMalformed,
                  dialect == Dialect::kColaB ? next_start(1) : frame_bytes);
  }
  telegram.dialect = dialect;
  telegram.start_offset = candidate_offset();
  telegram.stamp_ns = candidate_stamp();
  if (framing_ == Framing::kDetect) {
    framing_ = dialect == Dialect::kColaB ? Framing::kColaB : Framing::kColaA;
  }
  Step step{consumed};
  if (is_scan_telegram(telegram)) {
    std::optional<DropReason> failure;
    if (dialect == Dialect::kColaB) {
      BinaryReader reader(telegram.payload);
      failure = ScanParser<BinaryReader>(reader, scan_info_, scan_).parse();
    } else {
      AsciiReader reader(text_of(telegram.payload));
      failure = ScanParser<AsciiReader>(reader, scan_info_, scan_).parse();
    }
    if (failure) {
      // A CoLa B frame with a damaged length can still match the XOR (1 in 256) and then fail
      // here: the next telegram may begin inside it, so it is searched again.
      return reject(consumed, *failure, dialect == Dialect::kColaB ? next_start(1) : frame_bytes);
    }
    fill_scan(scan_info_, telegram, config_, scan_);
    classify_beams(config_, scan_);
    scans_.increment();
    step.scan = &scan_;
    step.scan_info = &scan_info_;
  }
  telegrams_.increment();
  delivered_ = frame_bytes;
  step.telegram = &telegram;
  return step;
}

// --- encoding

std::size_t frame_cola_b(std::span<const std::uint8_t> body, std::span<std::uint8_t> out) noexcept {
  const std::size_t frame_bytes = body.size() + kColaBOverheadBytes;
  if (out.size() < frame_bytes || body.size() > kMaxColaBBodyBytes) {
    return 0;
  }
  const auto length = static_cast<std::uint32_t>(body.size());
  for (std::size_t k = 0; k < 4; ++k) {
    out[k] = kStx;
    out[4 + k] = static_cast<std::uint8_t>(length >> (24U - 8U * k));
  }
  std::copy(body.begin(), body.end(), out.begin() + kColaBHeaderBytes);
  out[frame_bytes - 1] = checksum(body);
  return frame_bytes;
}

std::size_t frame_cola_a(std::string_view body, std::span<std::uint8_t> out) noexcept {
  if (out.size() < body.size() + 2) {
    return 0;
  }
  out[0] = kStx;
  std::copy(body.begin(), body.end(), out.begin() + 1);
  out[body.size() + 1] = kEtx;
  return body.size() + 2;
}

TelegramWriter::TelegramWriter(Dialect dialect, std::span<std::uint8_t> out, std::string_view type,
                               std::string_view command) noexcept
    : dialect_(dialect), out_(out) {
  if (dialect_ == Dialect::kColaB) {
    put_be(0x02020202U, 4);
    put_be(0, 4);  // the length, filled in by finish()
  } else {
    put(kStx);
  }
  put_text(type);
  if (!command.empty()) {
    put(' ');
    put_text(command);
  }
}

void TelegramWriter::put(std::uint8_t byte) noexcept {
  if (length_ < out_.size()) {
    out_[length_++] = byte;
  } else {
    overflow_ = true;
  }
}

void TelegramWriter::put_text(std::string_view text) noexcept {
  for (char c : text) {
    put(static_cast<std::uint8_t>(c));
  }
}

void TelegramWriter::put_be(std::uint32_t value, int bytes) noexcept {
  for (int k = bytes - 1; k >= 0; --k) {
    put(static_cast<std::uint8_t>(value >> (8U * static_cast<unsigned>(k))));
  }
}

void TelegramWriter::put_hex(std::uint32_t value, int min_digits) noexcept {
  constexpr std::string_view kDigits = "0123456789ABCDEF";
  int digits = 1;
  while (digits < 8 && (value >> (4U * static_cast<unsigned>(digits))) != 0) {
    ++digits;
  }
  digits = std::max(digits, min_digits);
  for (int k = digits - 1; k >= 0; --k) {
    put(static_cast<std::uint8_t>(kDigits[(value >> (4U * static_cast<unsigned>(k))) & 0xFU]));
  }
}

// CoLa A separates every field by a space; CoLa B has one space after the command name.
void TelegramWriter::separator() noexcept {
  if (dialect_ == Dialect::kColaA || !has_argument_) {
    put(' ');
  }
  has_argument_ = true;
}

TelegramWriter& TelegramWriter::u8(std::uint8_t value) noexcept {
  separator();
  if (dialect_ == Dialect::kColaB) {
    put(value);
  } else {
    put_hex(value, 1);
  }
  return *this;
}

TelegramWriter& TelegramWriter::u16(std::uint16_t value) noexcept {
  separator();
  if (dialect_ == Dialect::kColaB) {
    put_be(value, 2);
  } else {
    put_hex(value, 1);
  }
  return *this;
}

TelegramWriter& TelegramWriter::u32(std::uint32_t value) noexcept {
  separator();
  if (dialect_ == Dialect::kColaB) {
    put_be(value, 4);
  } else {
    put_hex(value, 1);
  }
  return *this;
}

TelegramWriter& TelegramWriter::i32(std::int32_t value) noexcept {
  return u32(static_cast<std::uint32_t>(value));  // two's complement in both dialects
}

TelegramWriter& TelegramWriter::f32(float value) noexcept {
  separator();
  const auto bits = std::bit_cast<std::uint32_t>(value);
  if (dialect_ == Dialect::kColaB) {
    put_be(bits, 4);
  } else {
    put_hex(bits, 8);
  }
  return *this;
}

TelegramWriter& TelegramWriter::u16_decimal(std::uint16_t value) noexcept {
  separator();
  if (dialect_ == Dialect::kColaB) {
    put_be(value, 2);
    return *this;
  }
  std::array<char, 8> text{};
  const auto [end, error] = std::to_chars(text.data(), text.data() + text.size(), value);
  put('+');
  put_text(std::string_view(text.data(), static_cast<std::size_t>(end - text.data())));
  return *this;
}

TelegramWriter& TelegramWriter::name(std::string_view text) noexcept {
  separator();
  put_text(text);
  return *this;
}

TelegramWriter& TelegramWriter::string(std::string_view text) noexcept {
  if (text.size() > std::numeric_limits<std::uint16_t>::max()) {
    overflow_ = true;
    return *this;
  }
  separator();
  const auto length = static_cast<std::uint16_t>(text.size());
  if (dialect_ == Dialect::kColaB) {
    put_be(length, 2);
  } else {
    put_hex(length, 1);
    put(' ');
  }
  put_text(text);
  return *this;
}

std::size_t TelegramWriter::finish() noexcept {
  if (dialect_ == Dialect::kColaA) {
    put(kEtx);
    return overflow_ ? 0 : length_;
  }
  if (overflow_) {
    return 0;
  }
  const std::size_t body_bytes = length_ - kColaBHeaderBytes;
  put(checksum(out_.subspan(kColaBHeaderBytes, body_bytes)));
  if (overflow_) {
    return 0;
  }
  for (std::size_t k = 0; k < 4; ++k) {
    out_[4 + k] = static_cast<std::uint8_t>(body_bytes >> (24U - 8U * k));
  }
  return length_;
}

std::size_t encode_command(Dialect dialect, std::string_view type, std::string_view command,
                           std::span<std::uint8_t> out) noexcept {
  return TelegramWriter(dialect, out, type, command).finish();
}

std::size_t encode_set_access_mode(Dialect dialect, std::uint8_t level, std::uint32_t password_hash,
                                   std::span<std::uint8_t> out) noexcept {
  return TelegramWriter(dialect, out, "sMN", "SetAccessMode").u8(level).u32(password_hash).finish();
}

// 13 bytes in CoLa B, 12 tokens in CoLa A: output channel, a reserved 0, remission, resolution,
// unit, encoder, a reserved 0, position, device name, comment, time, output interval. The S14
// log frame (01 00 01 00 00 00 00 00 00 00 01 00 01), the five captures' frames and S15's
// "%02X 00 %d %d 0 %02X 00 %d %d 0 %d +%d" agree on this reading.
std::size_t encode_scan_data_config(Dialect dialect, const ScanDataConfig& config,
                                    std::span<std::uint8_t> out) noexcept {
  const auto flag = [](bool value) { return static_cast<std::uint8_t>(value ? 1 : 0); };
  return TelegramWriter(dialect, out, "sWN", "LMDscandatacfg")
      .u8(config.output_channel)
      .u8(0)
      .u8(flag(config.rssi))
      .u8(flag(config.rssi_16bit))
      .u8(config.unit)
      .u8(config.encoder)
      .u8(0)
      .u8(flag(config.position))
      .u8(flag(config.device_name))
      .u8(flag(config.comment))
      .u8(flag(config.time))
      .u16_decimal(config.output_interval)
      .finish();
}

std::size_t encode_start_measurement(Dialect dialect, std::span<std::uint8_t> out) noexcept {
  return encode_command(dialect, "sMN", "LMCstartmeas", out);
}

std::size_t encode_run(Dialect dialect, std::span<std::uint8_t> out) noexcept {
  return encode_command(dialect, "sMN", "Run", out);
}

std::size_t encode_scan_events(Dialect dialect, bool enable, std::span<std::uint8_t> out) noexcept {
  return TelegramWriter(dialect, out, "sEN", "LMDscandata")
      .u8(static_cast<std::uint8_t>(enable ? 1 : 0))
      .finish();
}

std::size_t encode_scan_poll(Dialect dialect, std::span<std::uint8_t> out) noexcept {
  return encode_command(dialect, "sRN", "LMDscandata", out);
}

namespace {

void write_channel(TelegramWriter& writer, std::string_view name, std::uint8_t bits,
                   std::int32_t start_1e4deg, std::uint16_t step_1e4deg, std::size_t count,
                   const auto& value_of) noexcept {
  writer.name(name)
      .f32(1.0F)
      .f32(0.0F)
      .i32(start_1e4deg)
      .u16(step_1e4deg)
      .u16(static_cast<std::uint16_t>(count));
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t value = value_of(i);
    if (bits == 16) {
      writer.u16(static_cast<std::uint16_t>(value));
    } else {
      writer.u8(static_cast<std::uint8_t>(value));
    }
  }
}

}  // namespace

std::size_t encode_scan(Dialect dialect, const msg::LaserScan& scan,
                        const ScanTelegramFields& fields, std::span<std::uint8_t> out) noexcept {
  const std::size_t n = scan.beam_count;
  const double start_1e4deg =
      (scan.start_angle_rad / kRadiansPerDegree - kScannerFrameMinusSickDeg) / kDegreesPerAngleUnit;
  const double step_1e4deg = scan.angle_increment_rad / kRadiansPerDegree / kDegreesPerAngleUnit;
  if (n > msg::kMaxLaserBeams || !(std::abs(start_1e4deg) < 2.0e9) || !(step_1e4deg >= 0.0) ||
      step_1e4deg > 65535.0) {
    return 0;
  }
  const auto start = static_cast<std::int32_t>(std::lround(start_1e4deg));
  const auto step = static_cast<std::uint16_t>(std::lround(step_1e4deg));
  const std::uint32_t scan_centihz =
      scan.scan_period_s > 0.0 ? rounded_u32(100.0 / scan.scan_period_s, 4.0e9) : 0;
  const std::uint32_t measurement_hectohz =
      scan.time_increment_s > 0.0 ? rounded_u32(0.01 / scan.time_increment_s, 4.0e9) : 0;

  TelegramWriter w(dialect, out, fields.type, "LMDscandata");
  w.u16(fields.version).u16(fields.device_number).u32(fields.serial_number).u8(0).u8(0);
  w.u16(fields.telegram_counter).u16(static_cast<std::uint16_t>(scan.scan_counter & 0xFFFFU));
  w.u32(fields.time_since_startup_us).u32(fields.time_of_transmission_us);
  w.u8(0).u8(0).u8(0).u8(0).u16(0);                     // digital inputs, outputs, reserved
  w.u32(scan_centihz).u32(measurement_hectohz).u16(0);  // no encoders

  const bool rssi8 = scan.has_intensities && !fields.rssi_16bit;
  const bool rssi16 = scan.has_intensities && fields.rssi_16bit;
  w.u16(static_cast<std::uint16_t>(rssi16 ? 2 : 1));
  write_channel(w, "DIST1", 16, start, step, n, [&scan](std::size_t i) {
    return scan.status[i] == msg::BeamStatus::kValid
               ? rounded_u32(static_cast<double>(scan.ranges_m[i]) * 1000.0, 65535.0)
               : 0U;
  });
  const auto rssi_of = [&scan, rssi16](std::size_t i) {
    return rounded_u32(static_cast<double>(scan.intensities[i]), rssi16 ? 65535.0 : 255.0);
  };
  if (rssi16) {
    write_channel(w, "RSSI1", 16, start, step, n, rssi_of);
  }
  w.u16(static_cast<std::uint16_t>(rssi8 ? 1 : 0));
  if (rssi8) {
    write_channel(w, "RSSI1", 8, start, step, n, rssi_of);
  }
  w.u16(0).u16(0).u16(0);  // no position, device name or comment blocks
  w.u16(static_cast<std::uint16_t>(fields.has_device_time ? 1 : 0));
  if (fields.has_device_time) {
    const DeviceTime& t = fields.device_time;
    w.u16(t.year).u8(t.month).u8(t.day).u8(t.hour).u8(t.minute).u8(t.second).u32(t.microsecond);
  }
  w.u16(0);  // no event block
  return w.finish();
}

}  // namespace blockmap::hal::protocol::sick_cola
