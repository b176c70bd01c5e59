// SICK LMS 200 / 291 telegram codec (docs/protocols.md section 2). One byte-at-a-time state
// machine frames telegrams; small functions encode requests and read the B0 measured values.
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "blockmap/core/angles.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "blockmap/core/check.hpp"

namespace blockmap::hal::protocol::sick_lms2xx {
namespace {

constexpr std::size_t kHeaderBytes = 4;  // STX, ADDR, LEN_lo, LEN_hi
constexpr std::size_t kCrcBytes = 2;
constexpr std::uint8_t kReplyAddressBit = 0x80;
// LEN counts CMD + data (+ STATUS for replies) (2.2): at least the command, and the status.
constexpr std::size_t kMinRequestLength = 1;
constexpr std::size_t kMinReplyLength = 2;

// Count word (2.6): bits 0-9 the value count, bit 13 the partial-scan flag, 14-15 the units.
constexpr std::uint16_t kCountMask = 0x03FF;
constexpr std::uint16_t kPartialScanBit = 0x2000;
constexpr unsigned kUnitsShift = 14;
constexpr std::size_t kCountWordBytes = 2;
// The optional real-time scan index and telegram index after the values (one byte each, S7);
// the default stream has neither [2.6: UNVERIFIED which modes add the telegram index].
constexpr std::size_t kMaxTrailingBytes = 2;

// Reserved range codes, as distances below the range mask (2.6: 1FFF not valid, 1FFE dazzle,
// 1FFD operation overflow, 1FFB SNR too small, 1FFA channel-1 read error, 1FF7 value > max
// [single: S8]; 14/15-bit modes use 3FFx/7FFx the same way).
constexpr std::uint16_t kNotValidBelowMask = 0;
constexpr std::uint16_t kDazzleBelowMask = 1;
constexpr std::uint16_t kOverflowBelowMask = 2;
constexpr std::uint16_t kLowSnrBelowMask = 4;
constexpr std::uint16_t kReadErrorBelowMask = 5;
constexpr std::uint16_t kAboveMaxBelowMask = 8;

constexpr std::array<VariantGeometry, 5> kGeometries = {{
    {180, 100, 181},
    {180, 50, 361},
    {100, 100, 101},
    {100, 50, 201},
    {100, 25, 401},
}};

// The largest B0 fits a LaserScan: 401 values in an 812-byte telegram (2.6 sizes).
static_assert((kMaxBodyBytes - 1 - kCountWordBytes - 1) / 2 == 401);
static_assert(401 <= msg::kMaxLaserBeams);

std::uint16_t range_mask_of(std::uint8_t range_bits) {
  BLOCKMAP_CHECK_MSG(range_bits >= 13 && range_bits <= 15,
                     "LMS2xx range bits must be 13, 14 or 15 (docs/protocols.md 2.6)");
  return static_cast<std::uint16_t>((1U << range_bits) - 1U);
}

std::uint16_t read_u16(const std::uint8_t* bytes) noexcept {
  return static_cast<std::uint16_t>(bytes[0] | (bytes[1] << 8));
}

void write_u16(std::uint8_t* bytes, std::uint16_t value) noexcept {
  bytes[0] = static_cast<std::uint8_t>(value & 0xFFU);
  bytes[1] = static_cast<std::uint8_t>(value >> 8);
}

// Room for a body of `body_bytes` in `out`, within the 812-byte limit.
bool fits(std::span<const std::uint8_t> out, std::size_t body_bytes) noexcept {
  return body_bytes >= 1 && body_bytes <= kMaxBodyBytes &&
         out.size() >= body_bytes + kFrameOverheadBytes;
}

// Writes STX, ADDR, LEN around a body already at out[4..] and appends the CRC.
std::size_t close_frame(std::span<std::uint8_t> out, std::uint8_t address,
                        std::size_t body_bytes) noexcept {
  out[0] = kStx;
  out[1] = address;
  write_u16(&out[2], static_cast<std::uint16_t>(body_bytes));
  const std::size_t crc_at = kHeaderBytes + body_bytes;
  write_u16(&out[crc_at], crc16(out.first(crc_at)));
  return crc_at + kCrcBytes;
}

msg::BeamStatus beam_status(std::uint16_t code, std::uint16_t mask) noexcept {
  if (code + kAboveMaxBelowMask < mask) {
    return msg::BeamStatus::kValid;
  }
  switch (mask - code) {
    case kNotValidBelowMask:
    case kOverflowBelowMask:
    case kLowSnrBelowMask:
    case kReadErrorBelowMask:
      return msg::BeamStatus::kDeviceError;
    case kDazzleBelowMask:
      return msg::BeamStatus::kDazzled;
    case kAboveMaxBelowMask:  // "treat as no return / infinity" (2.6)
      return msg::BeamStatus::kNoReturn;
    default:
      return msg::BeamStatus::kValid;  // 1FF8, 1FF9, 1FFC are not reserved: plain ranges
  }
}

// Commands delivered as telegrams (2.2, 2.5); other valid telegrams are counted as unsupported.
bool is_known_reply(std::uint8_t reply) noexcept {
  switch (reply) {
    case command::kPowerOn:
    case command::kResetAck:
    case command::kNotAcknowledged:
    case command::kSwitchModeReply:
    case command::kMeasuredValues:
    case command::kStatusReply:
    case command::kSubRangeValues:
    case command::kDeviceTypeReply:
    case command::kVariantReply:
    case command::kConfigurationReply:
    case command::kWriteConfigurationReply:
      return true;
    default:
      return false;
  }
}

bool is_known_request(std::uint8_t request) noexcept {
  switch (request) {
    case command::kReset:
    case command::kSwitchMode:
    case command::kRequestValues:
    case command::kStatus:
    case command::kDeviceType:
    case command::kVariant:
    case command::kReadConfiguration:
    case command::kWriteConfiguration:
      return true;
    default:
      return false;
  }
}

}  // namespace

// --- names and tables

const char* to_string(Units units) noexcept {
  return units == Units::kMm ? "mm" : "cm";
}

double metres_per_unit(Units units) noexcept {
  return units == Units::kMm ? 0.001 : 0.01;
}

const char* to_string(AngularVariant variant) noexcept {
  switch (variant) {
    case AngularVariant::k180Deg1Deg:
      return "180/1";
    case AngularVariant::k180DegHalfDeg:
      return "180/0.5";
    case AngularVariant::k100Deg1Deg:
      return "100/1";
    case AngularVariant::k100DegHalfDeg:
      return "100/0.5";
    case AngularVariant::k100DegQuarterDeg:
      return "100/0.25";
  }
  return "?";
}

VariantGeometry geometry(AngularVariant variant) noexcept {
  return kGeometries[static_cast<std::size_t>(variant)];
}

std::optional<AngularVariant> variant_from_count(std::size_t count) noexcept {
  for (std::size_t v = 0; v < kGeometries.size(); ++v) {
    if (kGeometries[v].value_count == count) {
      return static_cast<AngularVariant>(v);
    }
  }
  return std::nullopt;
}

std::optional<std::uint8_t> range_bits_of_measuring_mode(std::uint8_t mode) noexcept {
  if (mode <= 0x02) {
    return std::uint8_t{13};
  }
  if (mode <= 0x05) {
    return std::uint8_t{14};
  }
  if (mode == 0x06) {
    return std::uint8_t{15};
  }
  return std::nullopt;  // 0F "32 m immediate" and 3F reflectivity: bit layout not documented
}

double range_max_m(Units units, std::uint8_t range_bits) {
  (void)range_mask_of(range_bits);  // checks the argument
  // 8 / 16 / 32 m in mm [solid for 8 m; 16 and 32 m single: S7, S8]; cm: ten times as far
  // [8/80 m solid; 160/320 m single: S8].
  const double range_mm_units_m = 8.0 * static_cast<double>(1U << (range_bits - 13U));
  return units == Units::kMm ? range_mm_units_m : 10.0 * range_mm_units_m;
}

const char* to_string(DropReason reason) noexcept {
  switch (reason) {
    case DropReason::kGarbage:
      return "garbage";
    case DropReason::kBadLength:
      return "bad_length";
    case DropReason::kBadCrc:
      return "bad_crc";
    case DropReason::kTruncated:
      return "truncated";
    case DropReason::kMalformed:
      return "malformed";
    case DropReason::kUnsupported:
      return "unsupported";
    case DropReason::kCount:
      break;
  }
  return "?";
}

msg::DeviceSeverity severity_of_status(std::uint8_t status) noexcept {
  using msg::DeviceSeverity;
  DeviceSeverity severity = DeviceSeverity::kWarning;  // codes 5-7 are not defined in 2.7
  switch (status & 0x07U) {
    case 0:
      severity = DeviceSeverity::kOk;
      break;
    case 1:
      severity = DeviceSeverity::kInfo;
      break;
    case 2:
      severity = DeviceSeverity::kWarning;
      break;
    case 3:
      severity = DeviceSeverity::kError;
      break;
    case 4:
      severity = DeviceSeverity::kFatal;
      break;
    default:
      break;
  }
  // Pollution (0x80) [S8, S9] and implausible values (0x40) [S8; UNVERIFIED against S9's 0x30]
  // degrade the measurements; a restart (0x20) is worth knowing. 0x10 has no known meaning.
  const auto at_least = [&severity](DeviceSeverity floor) { severity = std::max(severity, floor); };
  if ((status & 0xC0U) != 0) {
    at_least(DeviceSeverity::kWarning);
  }
  if ((status & 0x20U) != 0) {
    at_least(DeviceSeverity::kInfo);
  }
  return severity;
}

// --- CRC (2.3): shift with feedback 0x8005, then xor in (previous byte << 8) | byte.

std::uint16_t crc16(std::span<const std::uint8_t> bytes) noexcept {
  std::uint16_t crc = 0;
  std::uint8_t previous = 0;
  for (const std::uint8_t byte : bytes) {
    if ((crc & 0x8000U) != 0) {
      crc = static_cast<std::uint16_t>(((crc & 0x7FFFU) << 1) ^ 0x8005U);
    } else {
      crc = static_cast<std::uint16_t>(crc << 1);
    }
    crc = static_cast<std::uint16_t>(crc ^ ((previous << 8) | byte));
    previous = byte;
  }
  return crc;
}

// --- encoders

std::size_t encode_telegram(std::span<std::uint8_t> out, std::uint8_t address,
                            std::span<const std::uint8_t> body) noexcept {
  if (!fits(out, body.size())) {
    return 0;
  }
  std::copy(body.begin(), body.end(), out.begin() + kHeaderBytes);
  return close_frame(out, address, body.size());
}

std::size_t encode_request(std::span<std::uint8_t> out,
                           std::span<const std::uint8_t> command_and_data) noexcept {
  return encode_telegram(out, kHostAddress, command_and_data);
}

std::size_t encode_status_request(std::span<std::uint8_t> out) noexcept {
  const std::array<std::uint8_t, 1> body = {command::kStatus};
  return encode_request(out, body);
}

std::size_t encode_device_type_request(std::span<std::uint8_t> out) noexcept {
  const std::array<std::uint8_t, 1> body = {command::kDeviceType};
  return encode_request(out, body);
}

std::size_t encode_read_configuration(std::span<std::uint8_t> out) noexcept {
  const std::array<std::uint8_t, 1> body = {command::kReadConfiguration};
  return encode_request(out, body);
}

std::size_t encode_request_scan(std::span<std::uint8_t> out) noexcept {
  const std::array<std::uint8_t, 2> body = {command::kRequestValues, 0x01};
  return encode_request(out, body);
}

std::size_t encode_installation_mode(std::span<std::uint8_t> out,
                                     std::string_view password) noexcept {
  constexpr std::size_t kPasswordBytes = 8;
  if (password.size() != kPasswordBytes) {
    return 0;
  }
  std::array<std::uint8_t, 2 + kPasswordBytes> body = {command::kSwitchMode, mode::kInstallation};
  std::transform(password.begin(), password.end(), body.begin() + 2,
                 [](char c) { return static_cast<std::uint8_t>(c); });
  return encode_request(out, body);
}

std::size_t encode_continuous_output(std::span<std::uint8_t> out) noexcept {
  const std::array<std::uint8_t, 2> body = {command::kSwitchMode, mode::kContinuousAllValues};
  return encode_request(out, body);
}

std::size_t encode_stop_continuous_output(std::span<std::uint8_t> out) noexcept {
  const std::array<std::uint8_t, 2> body = {command::kSwitchMode, mode::kValuesOnRequest};
  return encode_request(out, body);
}

std::optional<std::uint8_t> baud_mode(std::uint32_t baud_bps) noexcept {
  switch (baud_bps) {
    case 9600:
      return mode::kBaud9600;
    case 19200:
      return mode::kBaud19200;
    case 38400:
      return mode::kBaud38400;
    case 500000:
      return mode::kBaud500000;
    default:
      return std::nullopt;
  }
}

std::size_t encode_set_baud(std::span<std::uint8_t> out, std::uint32_t baud_bps) noexcept {
  const std::optional<std::uint8_t> baud = baud_mode(baud_bps);
  if (!baud) {
    return 0;
  }
  const std::array<std::uint8_t, 2> body = {command::kSwitchMode, *baud};
  return encode_request(out, body);
}

std::size_t encode_variant(std::span<std::uint8_t> out, AngularVariant variant) noexcept {
  const VariantGeometry g = geometry(variant);
  std::array<std::uint8_t, 5> body = {command::kVariant};
  write_u16(&body[1], g.field_deg);
  write_u16(&body[3], g.resolution_centideg);
  return encode_request(out, body);
}

std::size_t encode_reply(std::span<std::uint8_t> out, std::uint8_t reply_command,
                         std::span<const std::uint8_t> data, std::uint8_t status,
                         std::uint8_t address) noexcept {
  const std::size_t body_bytes = 1 + data.size() + 1;
  if (!fits(out, body_bytes)) {
    return 0;
  }
  out[kHeaderBytes] = reply_command;
  std::copy(data.begin(), data.end(), out.begin() + kHeaderBytes + 1);
  out[kHeaderBytes + 1 + data.size()] = status;
  return close_frame(out, address, body_bytes);
}

std::size_t encode_measured_values(std::span<std::uint8_t> out,
                                   std::span<const std::uint16_t> values, Units units,
                                   std::uint8_t status, std::uint8_t address) noexcept {
  const std::size_t body_bytes = 1 + kCountWordBytes + 2 * values.size() + 1;
  if (values.size() > kCountMask || !fits(out, body_bytes)) {
    return 0;
  }
  std::uint8_t* body = &out[kHeaderBytes];
  body[0] = command::kMeasuredValues;
  const auto units_bits = static_cast<unsigned>(units) << kUnitsShift;
  write_u16(&body[1], static_cast<std::uint16_t>(values.size() | units_bits));
  for (std::size_t i = 0; i < values.size(); ++i) {
    write_u16(&body[1 + kCountWordBytes + 2 * i], values[i]);
  }
  body[body_bytes - 1] = status;
  return close_frame(out, address, body_bytes);
}

std::uint16_t encode_beam(double range_m, msg::BeamStatus status, Units units,
                          std::uint8_t range_bits) {
  const std::uint16_t mask = range_mask_of(range_bits);
  const auto reserved = [mask](std::uint16_t below_mask) {
    return static_cast<std::uint16_t>(mask - below_mask);
  };
  switch (status) {
    case msg::BeamStatus::kValid:
      break;
    case msg::BeamStatus::kNoReturn:
      return reserved(kAboveMaxBelowMask);
    case msg::BeamStatus::kDazzled:
      return reserved(kDazzleBelowMask);
    case msg::BeamStatus::kDeviceError:
    case msg::BeamStatus::kTooClose:
      return reserved(kNotValidBelowMask);
  }
  const double range_units = range_m / metres_per_unit(units);
  if (!(range_units >= 0.0)) {  // negative or not a number
    return reserved(kNotValidBelowMask);
  }
  // The largest plain range sits just below the first reserved code (1FF6 in 13-bit mode).
  if (range_units >= static_cast<double>(reserved(kAboveMaxBelowMask)) - 0.5) {
    return reserved(kAboveMaxBelowMask);
  }
  return static_cast<std::uint16_t>(std::lround(range_units));
}

// --- decoder

Decoder::Decoder(const Config& config)
    : config_(config), range_mask_(range_mask_of(config.range_bits)) {}

Decoder::Step Decoder::push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns) {
  return run(bytes, rx_stamp_ns, false);
}

Decoder::Step Decoder::flush() {
  return run({}, 0, true);
}

Decoder::Step Decoder::run(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns,
                           bool end_of_input) {
  std::size_t used = 0;
  for (;;) {
    // Bytes of a rejected candidate first: they came before any new input.
    while (replay_next_ < replay_end_) {
      const std::size_t at = replay_next_++;
      Step step = on_byte(frame_[at], stamps_[at], replay_offset_++, true);
      if (step.event != Event::kNone) {
        step.consumed = used;  // the event came from bytes consumed earlier
        return step;
      }
    }
    replay_next_ = 0;
    replay_end_ = 0;
    if (used == bytes.size()) {
      break;
    }
    Step step = on_byte(bytes[used++], rx_stamp_ns, stream_offset_++, false);
    if (step.event != Event::kNone) {
      step.consumed = used;
      return step;
    }
  }
  if (end_of_input && frame_length_ > 0) {
    return reject(DropReason::kTruncated);
  }
  return Step{bytes.size()};
}

Decoder::Step Decoder::on_byte(std::uint8_t byte, TimestampNs stamp_ns, std::uint64_t offset,
                               bool replayed) {
  if (frame_length_ == 0) {
    return hunt(byte, stamp_ns, offset, replayed);
  }
  frame_[frame_length_] = byte;
  stamps_[frame_length_] = stamp_ns;
  ++frame_length_;
  if (frame_length_ == 2 && !address_accepted(byte)) {
    // An STX in noise, as Player's reader treats it (2.4): the STX alone is garbage.
    drops_.count(DropReason::kGarbage);
    replay_after_stx();
    return Step{};
  }
  if (frame_length_ == kHeaderBytes) {
    const std::size_t length = declared_telegram_bytes() - kFrameOverheadBytes;
    const bool reply = (frame_[1] & kReplyAddressBit) != 0;
    if (length < (reply ? kMinReplyLength : kMinRequestLength) || length > kMaxBodyBytes) {
      return reject(DropReason::kBadLength);
    }
  }
  if (frame_length_ > kHeaderBytes && frame_length_ == declared_telegram_bytes()) {
    return finish_telegram();
  }
  return Step{};
}

Decoder::Step Decoder::hunt(std::uint8_t byte, TimestampNs stamp_ns, std::uint64_t offset,
                            bool replayed) {
  if (byte == kStx) {
    frame_[0] = byte;
    stamps_[0] = stamp_ns;
    frame_offset_ = offset;
    frame_length_ = 1;
    return Step{};
  }
  // A lone 06 / 15 between telegrams is the scanner's answer to a request (2.4). Inside the
  // bytes of a rejected candidate it is far more likely a data byte of a damaged telegram, so
  // it is not reported (nor counted as a NAK) there.
  if (!replayed && (byte == kAckByte || byte == kNakByte)) {
    Step step;
    step.event = byte == kAckByte ? Event::kAck : Event::kNak;
    step.offset = offset;
    (byte == kAckByte ? acks_ : naks_).increment();
    return step;
  }
  drops_.count(DropReason::kGarbage);
  return Step{};
}

bool Decoder::address_accepted(std::uint8_t address) const noexcept {
  return !config_.require_reply_address || address == kReplyAddress;
}

std::size_t Decoder::declared_telegram_bytes() const noexcept {
  return std::size_t{read_u16(&frame_[2])} + kFrameOverheadBytes;
}

Decoder::Step Decoder::reject(DropReason reason) {
  drops_.count(reason);
  Step step;
  step.event = Event::kRejected;
  step.reason = reason;
  step.offset = frame_offset_;
  replay_after_stx();
  return step;
}

// Queues the candidate's bytes after its STX, then any bytes still waiting from an earlier
// rejection, to be examined again: a real telegram may have started inside the candidate.
void Decoder::replay_after_stx() {
  const std::size_t waiting = replay_end_ - replay_next_;
  BLOCKMAP_CHECK_MSG(waiting == 0 || replay_offset_ == frame_offset_ + frame_length_,
                     "LMS2xx replay bytes must follow the rejected candidate");
  const std::size_t kept = frame_length_ - 1;
  std::copy(frame_.begin() + 1, frame_.begin() + static_cast<std::ptrdiff_t>(frame_length_),
            frame_.begin());
  std::copy(stamps_.begin() + 1, stamps_.begin() + static_cast<std::ptrdiff_t>(frame_length_),
            stamps_.begin());
  // Moving left within the array: std::copy copies front to back, so the ranges may overlap.
  const auto first = static_cast<std::ptrdiff_t>(replay_next_);
  const auto last = static_cast<std::ptrdiff_t>(replay_end_);
  std::copy(frame_.begin() + first, frame_.begin() + last,
            frame_.begin() + static_cast<std::ptrdiff_t>(kept));
  std::copy(stamps_.begin() + first, stamps_.begin() + last,
            stamps_.begin() + static_cast<std::ptrdiff_t>(kept));
  replay_next_ = 0;
  replay_end_ = kept + waiting;
  replay_offset_ = frame_offset_ + 1;
  frame_length_ = 0;
}

Decoder::Step Decoder::finish_telegram() {
  const std::size_t crc_at = frame_length_ - kCrcBytes;
  if (crc16(std::span<const std::uint8_t>(frame_.data(), crc_at)) != read_u16(&frame_[crc_at])) {
    return reject(DropReason::kBadCrc);
  }
  frame_length_ = 0;  // a genuine telegram: its bytes are not examined again

  Telegram& t = telegram_;
  t.start_offset = frame_offset_;
  t.stamp_ns = stamps_[0];
  t.address = frame_[1];
  t.command = frame_[kHeaderBytes];
  t.has_status = (t.address & kReplyAddressBit) != 0;
  t.status = t.has_status ? frame_[crc_at - 1] : std::uint8_t{0};
  const std::size_t data_end = t.has_status ? crc_at - 1 : crc_at;
  t.data = std::span<const std::uint8_t>(&frame_[kHeaderBytes + 1], data_end - kHeaderBytes - 1);
  t.device_status.header = msg::Header{t.stamp_ns, config_.source_id};
  t.device_status.severity = t.has_status ? severity_of_status(t.status) : msg::DeviceSeverity::kOk;
  t.device_status.device_code = t.status;
  t.has_scan = false;

  if (!(t.has_status ? is_known_reply(t.command) : is_known_request(t.command))) {
    drops_.count(DropReason::kUnsupported);  // valid, just not ours: not an error
    return Step{};
  }
  if (t.has_status && t.command == command::kMeasuredValues) {
    if (const std::optional<DropReason> failure = read_measured_values()) {
      drops_.count(*failure);
      if (*failure == DropReason::kUnsupported) {
        return Step{};
      }
      Step step;
      step.event = Event::kRejected;
      step.reason = *failure;
      step.offset = frame_offset_;
      return step;
    }
    t.has_scan = true;
    scans_.increment();
  }
  telegrams_.increment();
  Step step;
  step.event = Event::kTelegram;
  step.telegram = &telegram_;
  return step;
}

// B0 (2.6): count word, value words, optional indices, then the status byte (not in `data`).
std::optional<DropReason> Decoder::read_measured_values() {
  Telegram& t = telegram_;
  if (t.data.size() < kCountWordBytes) {
    return DropReason::kMalformed;
  }
  t.count_word = read_u16(t.data.data());
  if ((t.count_word & kPartialScanBit) != 0) {
    // Interlaced partial scans: the index bits' meaning is UNVERIFIED (2.6), so no angles.
    return DropReason::kUnsupported;
  }
  const unsigned units = static_cast<unsigned>(t.count_word) >> kUnitsShift;
  if (units > static_cast<unsigned>(Units::kMm)) {
    return DropReason::kMalformed;  // 10 / 11: not defined (Player's "dm" is UNVERIFIED, 2.5)
  }
  t.units = static_cast<Units>(units);
  const std::size_t count = t.count_word & kCountMask;
  const std::size_t values_end = kCountWordBytes + 2 * count;
  if (t.data.size() < values_end || t.data.size() - values_end > kMaxTrailingBytes) {
    return DropReason::kMalformed;
  }
  t.trailing_bytes = t.data.size() - values_end;
  const std::optional<AngularVariant> variant =
      config_.variant ? config_.variant : variant_from_count(count);
  if (!variant || geometry(*variant).value_count != count) {
    return DropReason::kMalformed;
  }
  t.variant = *variant;

  msg::LaserScan& scan = t.scan;
  const VariantGeometry g = geometry(t.variant);
  scan.header = msg::Header{t.stamp_ns, config_.source_id};
  // Value 0 lies at the scanner's right-hand 0 deg mark, 90 deg is straight ahead (2.8).
  scan.start_angle_rad = -0.5 * static_cast<double>(g.field_deg) * kRadiansPerDegree;
  scan.angle_increment_rad = static_cast<double>(g.resolution_centideg) * 0.01 * kRadiansPerDegree;
  scan.time_increment_s = 0.0;  // not stated in docs/protocols.md
  scan.scan_period_s = 0.0;
  scan.range_min_m = 0.0;
  scan.range_max_m = range_max_m(t.units, config_.range_bits);
  scan.scan_counter = 0;
  scan.beam_count = static_cast<std::uint16_t>(count);
  scan.has_intensities = false;
  const double metres = metres_per_unit(t.units);
  for (std::size_t i = 0; i < count; ++i) {
    const auto code =
        static_cast<std::uint16_t>(read_u16(&t.data[kCountWordBytes + 2 * i]) & range_mask_);
    const msg::BeamStatus status = beam_status(code, range_mask_);
    scan.status[i] = status;
    scan.ranges_m[i] = status == msg::BeamStatus::kValid
                           ? static_cast<float>(static_cast<double>(code) * metres)
                           : 0.0F;
  }
  return std::nullopt;
}

}  // namespace blockmap::hal::protocol::sick_lms2xx
