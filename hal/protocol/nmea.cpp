// NMEA 0183 codec (docs/protocols.md section 5). One state machine frames sentences; one small
// function per sentence type reads its fields.
#include "blockmap/hal/protocol/nmea.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <optional>
#include <string_view>
#include <type_traits>

#include "blockmap/core/check.hpp"

namespace blockmap::hal::protocol::nmea {
namespace {

constexpr std::size_t kMaxFields = 48;
constexpr std::size_t kStandardSentenceBytes = 82;
constexpr double kMetresPerSecondPerKnot = 1852.0 / 3600.0;
constexpr double kMetresPerSecondPerKmh = 1000.0 / 3600.0;

// The fields of one sentence body, split at commas. Absent trailing fields read as empty:
// receivers that stop early (no DGPS fields) and ones that add fields (NMEA 4.1) both parse.
class Fields {
 public:
  explicit Fields(std::string_view body) {
    std::size_t start = 0;
    while (count_ < kMaxFields) {
      const std::size_t comma = body.find(',', start);
      fields_[count_++] =
          body.substr(start, comma == std::string_view::npos ? body.size() - start : comma - start);
      if (comma == std::string_view::npos) {
        return;
      }
      start = comma + 1;
    }
    overflow_ = true;
  }
  [[nodiscard]] std::string_view operator[](std::size_t index) const noexcept {
    return index < count_ ? fields_[index] : std::string_view();
  }
  // Fields after the address.
  [[nodiscard]] std::size_t data_count() const noexcept { return count_ == 0 ? 0 : count_ - 1; }
  [[nodiscard]] bool overflow() const noexcept { return overflow_; }

 private:
  std::array<std::string_view, kMaxFields> fields_{};
  std::size_t count_ = 0;
  bool overflow_ = false;
};

bool is_digit(char c) noexcept {
  return c >= '0' && c <= '9';
}

// A plain decimal ("-12.5", "0.98"); no exponent, no inf/nan, which from_chars would accept.
bool parse_decimal(std::string_view text, double& value) noexcept {
  if (text.empty()) {
    return false;
  }
  bool seen_digit = false;
  bool seen_point = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (is_digit(c)) {
      seen_digit = true;
    } else if (c == '.' && !seen_point) {
      seen_point = true;
    } else if (!((c == '-' || c == '+') && i == 0)) {
      return false;
    }
  }
  if (!seen_digit) {
    return false;
  }
  const char* first = text.data() + (text.front() == '+' ? 1 : 0);
  const auto [end, error] =
      std::from_chars(first, text.data() + text.size(), value, std::chars_format::fixed);
  return error == std::errc() && end == text.data() + text.size();
}

// A plain integer; a leading '+' is allowed (ZDA zone "+00"), which from_chars would refuse.
template <typename Integer>
bool parse_integer(std::string_view text, Integer& value) noexcept {
  if (!text.empty() && text.front() == '+') {
    text.remove_prefix(1);
  }
  if (text.empty() || (text.front() == '-' && !std::is_signed_v<Integer>)) {
    return false;
  }
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return error == std::errc() && end == text.data() + text.size();
}

// An optional numeric field: empty means absent (true, has = false); anything else must parse.
bool optional_decimal(std::string_view text, bool& has, double& value) noexcept {
  has = false;
  if (text.empty()) {
    return true;
  }
  has = parse_decimal(text, value);
  return has;
}

template <typename Integer>
bool optional_integer(std::string_view text, bool& has, Integer& value) noexcept {
  has = false;
  if (text.empty()) {
    return true;
  }
  has = parse_integer(text, value);
  return has;
}

// hhmmss[.s...] -> milliseconds of the UTC day.
bool parse_time(std::string_view text, bool& has, std::int32_t& milliseconds) noexcept {
  has = false;
  if (text.empty()) {
    return true;
  }
  if (text.size() < 6 || !is_digit(text[0]) || !is_digit(text[1]) || !is_digit(text[2]) ||
      !is_digit(text[3]) || !is_digit(text[4]) || !is_digit(text[5])) {
    return false;
  }
  const int hours = (text[0] - '0') * 10 + (text[1] - '0');
  const int minutes = (text[2] - '0') * 10 + (text[3] - '0');
  const int seconds = (text[4] - '0') * 10 + (text[5] - '0');
  if (hours > 23 || minutes > 59 || seconds > 60) {  // 60: a leap second
    return false;
  }
  double fraction = 0.0;
  if (text.size() > 6) {
    if (text[6] != '.' || !parse_decimal(text.substr(6), fraction)) {
      return false;
    }
  }
  milliseconds = ((hours * 60 + minutes) * 60 + seconds) * 1000 +
                 static_cast<std::int32_t>(std::lround(fraction * 1000.0));
  has = true;
  return true;
}

// ddmmyy -> date; two-digit years below 80 are 20xx (as minmea and gpsd read them).
bool parse_date(std::string_view text, msg::GpsFix& fix) noexcept {
  fix.has_date = false;
  if (text.empty()) {
    return true;
  }
  if (text.size() != 6) {
    return false;
  }
  for (char c : text) {
    if (!is_digit(c)) {
      return false;
    }
  }
  const int day = (text[0] - '0') * 10 + (text[1] - '0');
  const int month = (text[2] - '0') * 10 + (text[3] - '0');
  const int year = (text[4] - '0') * 10 + (text[5] - '0');
  if (day < 1 || day > 31 || month < 1 || month > 12) {
    return false;
  }
  fix.utc_day = static_cast<std::uint8_t>(day);
  fix.utc_month = static_cast<std::uint8_t>(month);
  fix.utc_year = static_cast<std::uint16_t>(year < 80 ? 2000 + year : 1900 + year);
  fix.has_date = true;
  return true;
}

// (d)ddmm.mmmm + hemisphere -> signed degrees. `max_degrees` is 90 or 180.
bool parse_angle(std::string_view value, std::string_view hemisphere, char positive, char negative,
                 double max_degrees, bool& has, double& degrees) noexcept {
  has = false;
  if (value.empty() && hemisphere.empty()) {
    return true;
  }
  double ddmm = 0.0;
  if (!parse_decimal(value, ddmm) || ddmm < 0.0 || hemisphere.size() != 1) {
    return false;
  }
  const double whole_degrees = std::floor(ddmm / 100.0);
  const double minutes = ddmm - whole_degrees * 100.0;
  if (minutes >= 60.0) {
    return false;
  }
  degrees = whole_degrees + minutes / 60.0;
  if (degrees > max_degrees) {
    return false;
  }
  if (hemisphere[0] == negative) {
    degrees = -degrees;
  } else if (hemisphere[0] != positive) {
    return false;
  }
  has = true;
  return true;
}

bool parse_position(const Fields& fields, std::size_t first, msg::GpsFix& fix) noexcept {
  bool has_latitude = false;
  bool has_longitude = false;
  if (!parse_angle(fields[first], fields[first + 1], 'N', 'S', 90.0, has_latitude,
                   fix.latitude_deg) ||
      !parse_angle(fields[first + 2], fields[first + 3], 'E', 'W', 180.0, has_longitude,
                   fix.longitude_deg)) {
    return false;
  }
  fix.has_position = has_latitude && has_longitude;
  return has_latitude == has_longitude;
}

// A one-letter field such as a status or an FAA mode; '\0' when empty.
bool parse_letter(std::string_view text, char& letter) noexcept {
  letter = '\0';
  if (text.empty()) {
    return true;
  }
  if (text.size() != 1) {
    return false;
  }
  letter = text[0];
  return true;
}

bool parse_gga(const Fields& f, msg::GpsFix& fix) noexcept {
  std::uint8_t quality = 0;
  if (!parse_time(f[1], fix.has_time, fix.utc_milliseconds_of_day) || !parse_position(f, 2, fix) ||
      !optional_integer(f[6], fix.has_quality, quality) || quality > 8) {
    return false;
  }
  fix.quality = static_cast<msg::GpsFixQuality>(quality);
  return optional_integer(f[7], fix.has_satellites, fix.satellites_used) &&
         optional_decimal(f[8], fix.has_hdop, fix.hdop) &&
         optional_decimal(f[9], fix.has_altitude, fix.altitude_msl_m) &&
         optional_decimal(f[11], fix.has_geoid_separation, fix.geoid_separation_m);
}

bool parse_rmc(const Fields& f, msg::GpsFix& fix, char& status, char& faa_mode) noexcept {
  double speed_knots = 0.0;
  if (!parse_time(f[1], fix.has_time, fix.utc_milliseconds_of_day) || !parse_letter(f[2], status) ||
      !parse_position(f, 3, fix) || !optional_decimal(f[7], fix.has_velocity, speed_knots) ||
      !optional_decimal(f[8], fix.has_course, fix.course_deg) || !parse_date(f[9], fix) ||
      !parse_letter(f[12], faa_mode)) {
    return false;
  }
  fix.speed_mps = speed_knots * kMetresPerSecondPerKnot;
  return status == 'A' || status == 'V';
}

bool parse_gll(const Fields& f, msg::GpsFix& fix, char& status, char& faa_mode) noexcept {
  return parse_position(f, 1, fix) && parse_time(f[5], fix.has_time, fix.utc_milliseconds_of_day) &&
         parse_letter(f[6], status) && parse_letter(f[7], faa_mode);
}

bool parse_gns(const Fields& f, msg::GpsFix& fix, bool& any_system_fixed) noexcept {
  any_system_fixed = false;
  for (char mode : f[6]) {
    any_system_fixed = any_system_fixed || mode != 'N';
  }
  return parse_time(f[1], fix.has_time, fix.utc_milliseconds_of_day) && parse_position(f, 2, fix) &&
         optional_integer(f[7], fix.has_satellites, fix.satellites_used) &&
         optional_decimal(f[8], fix.has_hdop, fix.hdop) &&
         optional_decimal(f[9], fix.has_altitude, fix.altitude_msl_m) &&
         optional_decimal(f[10], fix.has_geoid_separation, fix.geoid_separation_m);
}

bool parse_gsa(const Fields& f, GsaData& gsa) noexcept {
  const std::size_t n = f.data_count();
  if (n < 17) {
    return false;
  }
  char mode = '\0';
  bool has_fix_type = false;
  if (!parse_letter(f[1], mode) || !optional_integer(f[2], has_fix_type, gsa.fix_type) ||
      gsa.fix_type > 3) {
    return false;
  }
  gsa.automatic = mode == 'A';
  // 12 satellite fields, then PDOP, HDOP, VDOP, and since NMEA 4.10 a system id. Receivers that
  // report more than 12 satellites lengthen the list; the DOPs then close the sentence.
  const bool has_system_field = n == 18;
  const std::size_t dop_first = has_system_field ? 15 : n - 2;
  for (std::size_t i = 3; i < dop_first; ++i) {
    std::uint16_t id = 0;
    bool has_id = false;
    if (!optional_integer(f[i], has_id, id)) {
      return false;
    }
    if (has_id && gsa.satellite_count < kMaxGsaSatellites) {
      gsa.satellite_ids[gsa.satellite_count++] = id;
    }
  }
  if (!optional_decimal(f[dop_first], gsa.has_pdop, gsa.pdop) ||
      !optional_decimal(f[dop_first + 1], gsa.has_hdop, gsa.hdop) ||
      !optional_decimal(f[dop_first + 2], gsa.has_vdop, gsa.vdop)) {
    return false;
  }
  // SiRF-TriG puts a decimal where the system id belongs: keep it only when it is an integer.
  gsa.has_system_id = has_system_field && parse_integer(f[18], gsa.system_id);
  return true;
}

bool parse_gsv(const Fields& f, GsvData& gsv) noexcept {
  const std::size_t n = f.data_count();
  if (n < 3 || !parse_integer(f[1], gsv.sentence_count) ||
      !parse_integer(f[2], gsv.sentence_number)) {
    return false;
  }
  bool has_in_view = false;
  if (!optional_integer(f[3], has_in_view, gsv.satellites_in_view)) {
    return false;
  }
  const std::size_t block_fields = n - 3;
  const std::size_t blocks = block_fields / 4;
  if (blocks > 4 || block_fields % 4 > 1) {
    return false;
  }
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t first = 4 + 4 * b;
    SatelliteInView satellite;
    bool has_id = false;
    double snr = 0.0;
    if (!optional_integer(f[first], has_id, satellite.id) ||
        !optional_integer(f[first + 1], satellite.has_elevation, satellite.elevation_deg) ||
        !optional_integer(f[first + 2], satellite.has_azimuth, satellite.azimuth_deg) ||
        !optional_decimal(f[first + 3], satellite.has_snr, snr)) {
      return false;
    }
    satellite.snr_db = static_cast<float>(snr);
    if (has_id) {
      gsv.satellites[gsv.block_count++] = satellite;
    }
  }
  if (block_fields % 4 == 1) {
    gsv.has_signal_id = parse_integer(f[n], gsv.signal_id);
    return gsv.has_signal_id || f[n].empty();
  }
  return true;
}

bool parse_vtg(const Fields& f, msg::GpsFix& fix, VtgExtra& vtg, char& faa_mode) noexcept {
  double speed_knots = 0.0;
  double speed_kmh = 0.0;
  bool has_knots = false;
  bool has_kmh = false;
  if (!optional_decimal(f[1], fix.has_course, fix.course_deg) ||
      !optional_decimal(f[3], vtg.has_course_magnetic, vtg.course_magnetic_deg) ||
      !optional_decimal(f[5], has_knots, speed_knots) ||
      !optional_decimal(f[7], has_kmh, speed_kmh) || !parse_letter(f[9], faa_mode)) {
    return false;
  }
  fix.has_velocity = has_knots || has_kmh;
  fix.speed_mps =
      has_knots ? speed_knots * kMetresPerSecondPerKnot : speed_kmh * kMetresPerSecondPerKmh;
  return true;
}

bool parse_zda(const Fields& f, msg::GpsFix& fix, ZdaExtra& zda) noexcept {
  bool has_day = false;
  bool has_month = false;
  bool has_year = false;
  bool has_zone_minutes = false;
  if (!parse_time(f[1], fix.has_time, fix.utc_milliseconds_of_day) ||
      !optional_integer(f[2], has_day, fix.utc_day) ||
      !optional_integer(f[3], has_month, fix.utc_month) ||
      !optional_integer(f[4], has_year, fix.utc_year) ||
      !optional_integer(f[5], zda.has_zone, zda.zone_hours) ||
      !optional_integer(f[6], has_zone_minutes, zda.zone_minutes)) {
    return false;
  }
  if (has_day != has_month || has_month != has_year) {
    return false;
  }
  fix.has_date = has_day;
  return !fix.has_date || (fix.utc_day >= 1 && fix.utc_day <= 31 && fix.utc_month >= 1 &&
                           fix.utc_month <= 12 && fix.utc_year >= 1980);
}

// Printable ASCII other than '$': the characters a sentence body is made of.
constexpr std::array<bool, 256> kOrdinary = [] {
  std::array<bool, 256> table{};
  for (int c = 0x20; c <= 0x7E; ++c) table[static_cast<std::size_t>(c)] = c != '$';
  return table;
}();

// How many ordinary characters `bytes` starts with, at most `limit` (at least 1 is known).
std::size_t ordinary_run(std::span<const std::uint8_t> bytes, std::size_t limit) noexcept {
  const std::size_t end = std::min(bytes.size(), limit);
  std::size_t run = 1;
  while (run < end && kOrdinary[bytes[run]]) ++run;
  return run;
}

int hex_value(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

bool is_address_character(char c) noexcept {
  return (c >= 'A' && c <= 'Z') || is_digit(c);
}

msg::GpsFixMode mode_from_gsa(std::uint8_t fix_type) noexcept {
  switch (fix_type) {
    case 1:
      return msg::GpsFixMode::kNone;
    case 2:
      return msg::GpsFixMode::k2d;
    case 3:
      return msg::GpsFixMode::k3d;
    default:
      return msg::GpsFixMode::kUnknown;
  }
}

}  // namespace

const char* to_string(SentenceType type) noexcept {
  switch (type) {
    case SentenceType::kGga:
      return "GGA";
    case SentenceType::kRmc:
      return "RMC";
    case SentenceType::kGll:
      return "GLL";
    case SentenceType::kGns:
      return "GNS";
    case SentenceType::kGsa:
      return "GSA";
    case SentenceType::kGsv:
      return "GSV";
    case SentenceType::kVtg:
      return "VTG";
    case SentenceType::kZda:
      return "ZDA";
  }
  return "?";
}

const char* to_string(DropReason reason) noexcept {
  switch (reason) {
    case DropReason::kGarbage:
      return "garbage";
    case DropReason::kTooLong:
      return "too_long";
    case DropReason::kBadCharacter:
      return "bad_character";
    case DropReason::kTruncated:
      return "truncated";
    case DropReason::kMissingChecksum:
      return "missing_checksum";
    case DropReason::kBadChecksum:
      return "bad_checksum";
    case DropReason::kMalformed:
      return "malformed";
    case DropReason::kUnsupported:
      return "unsupported";
    case DropReason::kProprietary:
      return "proprietary";
    case DropReason::kCount:
      break;
  }
  return "?";
}

std::uint8_t checksum(std::span<const char> body) noexcept {
  std::uint8_t sum = 0;
  for (char c : body) {
    sum = static_cast<std::uint8_t>(sum ^ static_cast<std::uint8_t>(c));
  }
  return sum;
}

Decoder::Decoder(const Config& config) : config_(config) {
  BLOCKMAP_CHECK_MSG(
      config_.max_sentence_bytes >= 16 && config_.max_sentence_bytes <= kMaxSentenceBytes,
      "NMEA max_sentence_bytes must lie in [16, 256]");
}

Decoder::Step Decoder::push(std::span<const std::uint8_t> bytes, TimestampNs rx_stamp_ns) {
  // The body excludes '$' and the line end, which the byte limit includes.
  const std::size_t body_limit = config_.max_sentence_bytes - 3;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const auto c = static_cast<char>(bytes[i]);
    const std::uint64_t offset = stream_offset_++;
    if (state_ == State::kHunting) {
      if (c == '$') {
        state_ = State::kInSentence;
        line_length_ = 0;
        sentence_offset_ = offset;
        sentence_stamp_ns_ = rx_stamp_ns;
      } else if (c != '\r' && c != '\n') {
        drops_.count(DropReason::kGarbage);
      }
      continue;
    }
    if (c == '\r' || c == '\n') {
      state_ = State::kHunting;
      return finish_sentence(i + 1);
    }
    if (c == '$') {  // the sentence before was cut off; this '$' starts the next one
      Step step = reject(i + 1, DropReason::kTruncated);
      state_ = State::kInSentence;
      line_length_ = 0;
      sentence_offset_ = offset;
      sentence_stamp_ns_ = rx_stamp_ns;
      return step;
    }
    if (c < 0x20 || c > 0x7E) {
      state_ = State::kHunting;
      return reject(i + 1, DropReason::kBadCharacter);
    }
    if (line_length_ == body_limit) {
      state_ = State::kHunting;
      return reject(i + 1, DropReason::kTooLong);
    }
    // Fast path: copy the run of ordinary sentence characters that starts here in one go.
    const std::size_t run = ordinary_run(bytes.subspan(i), body_limit - line_length_);
    std::memcpy(line_.data() + line_length_, bytes.data() + i, run);
    line_length_ += run;
    stream_offset_ += run - 1;
    i += run - 1;
  }
  return Step{bytes.size()};
}

Decoder::Step Decoder::reject(std::size_t consumed, DropReason reason) {
  drops_.count(reason);
  Step step{consumed};
  step.rejected = true;
  step.reason = reason;
  step.start_offset = sentence_offset_;
  return step;
}

Decoder::Step Decoder::finish_sentence(std::size_t consumed) {
  std::span<const char> body(line_.data(), line_length_);
  const std::string_view text(line_.data(), line_length_);
  const std::size_t star = text.rfind('*');
  if (star == std::string_view::npos) {
    if (!config_.accept_missing_checksum) {
      return reject(consumed, DropReason::kMissingChecksum);
    }
  } else {
    const int high = star + 2 < text.size() ? hex_value(text[star + 1]) : -1;
    const int low = star + 2 < text.size() ? hex_value(text[star + 2]) : -1;
    if (star + 3 != text.size() || high < 0 || low < 0 ||
        checksum(body.first(star)) != static_cast<std::uint8_t>(high * 16 + low)) {
      return reject(consumed, DropReason::kBadChecksum);
    }
    body = body.first(star);
  }
  if (body.empty()) {
    return reject(consumed, DropReason::kMalformed);
  }
  if (body[0] == 'P') {
    drops_.count(DropReason::kProprietary);
    return Step{consumed};
  }
  if (const std::optional<DropReason> failure = parse(body)) {
    if (*failure == DropReason::kUnsupported) {  // well-formed, just not ours: not an error
      drops_.count(DropReason::kUnsupported);
      return Step{consumed};
    }
    return reject(consumed, *failure);
  }
  decoded_.increment();
  if (line_length_ + 3 > kStandardSentenceBytes) {
    long_.increment();
  }
  Step step{consumed};
  step.sentence = &sentence_;
  return step;
}

std::optional<DropReason> Decoder::parse(std::span<const char> body) {
  const Fields fields(std::string_view(body.data(), body.size()));
  const std::string_view address = fields[0];
  bool address_ok = address.size() >= 5 && !fields.overflow();
  for (char c : address) {
    address_ok = address_ok && is_address_character(c);
  }
  if (!address_ok) {
    return DropReason::kMalformed;
  }

  Sentence& s = sentence_;
  s = Sentence{};
  s.talker = {address[0], address[1], '\0'};
  s.start_offset = sentence_offset_;
  s.fix.header = msg::Header{sentence_stamp_ns_, config_.source_id};
  msg::GpsFix& fix = s.fix;

  const std::string_view type = address.substr(address.size() - 3);
  char status = '\0';
  char faa_mode = '\0';
  bool ok = false;
  if (type == "GGA") {
    s.type = SentenceType::kGga;
    ok = parse_gga(fields, fix);
    fix.valid = fix.has_quality && fix.quality != msg::GpsFixQuality::kInvalid;
  } else if (type == "RMC") {
    s.type = SentenceType::kRmc;
    ok = parse_rmc(fields, fix, status, faa_mode);
    fix.valid = status == 'A' && faa_mode != 'N';
  } else if (type == "GLL") {
    s.type = SentenceType::kGll;
    ok = parse_gll(fields, fix, status, faa_mode);
    fix.valid = fix.has_position && status != 'V' && faa_mode != 'N';
  } else if (type == "GNS") {
    s.type = SentenceType::kGns;
    bool any_system_fixed = false;
    ok = parse_gns(fields, fix, any_system_fixed);
    fix.valid = any_system_fixed && fix.has_position;
  } else if (type == "GSA") {
    s.type = SentenceType::kGsa;
    ok = parse_gsa(fields, s.gsa);
    if (ok && s.gsa.fix_type != 0) {
      last_gsa_fix_type_ = s.gsa.fix_type;
    }
    fix.mode = mode_from_gsa(s.gsa.fix_type);
  } else if (type == "GSV") {
    s.type = SentenceType::kGsv;
    ok = parse_gsv(fields, s.gsv);
  } else if (type == "VTG") {
    s.type = SentenceType::kVtg;
    ok = parse_vtg(fields, fix, s.vtg, faa_mode);
    fix.valid = fix.has_velocity && faa_mode != 'N';
  } else if (type == "ZDA") {
    s.type = SentenceType::kZda;
    ok = parse_zda(fields, fix, s.zda);
    fix.valid = fix.has_time;
  } else {
    return DropReason::kUnsupported;
  }
  if (!ok) {
    return DropReason::kMalformed;
  }
  if (s.type == SentenceType::kGga || s.type == SentenceType::kRmc ||
      s.type == SentenceType::kGll || s.type == SentenceType::kGns) {
    // Fix mode: "none" when the sentence itself says so, else what the last GSA reported.
    fix.mode = fix.valid ? mode_from_gsa(last_gsa_fix_type_) : msg::GpsFixMode::kNone;
  }
  return std::nullopt;
}

}  // namespace blockmap::hal::protocol::nmea
