// NMEA 0183 sentence encoders (a simulated GNSS receiver's output). docs/protocols.md section 5
// gives the field layouts; the decoder in nmea.cpp is their inverse.
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>

#include "blockmap/hal/protocol/nmea.hpp"

namespace blockmap::hal::protocol::nmea {
namespace {

constexpr double kKnotsPerMps = 3600.0 / 1852.0;

// Appends printf-formatted text at `length`; false when it does not fit. (snprintf formats
// without allocating; the attribute lets the compiler check every call's format.)
[[gnu::format(printf, 3, 4)]] bool append(std::span<char> out, std::size_t& length,
                                          const char* format, ...) {
  if (length >= out.size()) {
    return false;
  }
  std::va_list args;
  va_start(args, format);
  const int written = std::vsnprintf(out.data() + length, out.size() - length, format, args);
  va_end(args);
  if (written < 0 || static_cast<std::size_t>(written) >= out.size() - length) {
    return false;
  }
  length += static_cast<std::size_t>(written);
  return true;
}

bool append_text(std::span<char> out, std::size_t& length, const char* text) {
  return append(out, length, "%s", text);
}

// hhmmss.ss, or nothing.
bool append_time(std::span<char> out, std::size_t& length, const msg::GpsFix& fix) {
  if (!fix.has_time) {
    return true;
  }
  const std::int32_t centiseconds = (fix.utc_milliseconds_of_day + 5) / 10;
  const int hours = (centiseconds / 360000) % 24;
  const int minutes = (centiseconds / 6000) % 60;
  const int seconds = (centiseconds / 100) % 60;
  return append(out, length, "%02d%02d%02d.%02d", hours, minutes, seconds,
                static_cast<int>(centiseconds % 100));
}

// How finely a fix is written. A code fix: the fifth decimal of a minute (1.9 cm) and a
// decimetre of altitude, as most receivers write it. A carrier-phase (RTK) fix: the seventh
// (0.2 mm) and a millimetre, as RTK receivers do in their high-precision mode, since the fix
// itself is good to centimetres.
struct Precision {
  int minute_decimals = 5;
  int altitude_decimals = 1;
};

Precision precision_of(const msg::GpsFix& fix) {
  const bool carrier_phase = fix.has_quality && (fix.quality == msg::GpsFixQuality::kRtkFixed ||
                                                 fix.quality == msg::GpsFixQuality::kRtkFloat);
  return carrier_phase ? Precision{7, 3} : Precision{};
}

// ddmm.mmmmm,N (or dddmm.mmmmm,E), rounded to `decimals` of a minute: ",," when absent.
bool append_angle(std::span<char> out, std::size_t& length, bool present, double degrees,
                  int degree_digits, int decimals, char positive, char negative) {
  if (!present) {
    return append_text(out, length, ",");
  }
  const char hemisphere = degrees < 0.0 ? negative : positive;
  // Work in whole units of the last decimal so that rounding never prints 60.00000 minutes.
  std::int64_t per_minute = 1;
  for (int i = 0; i < decimals; ++i) {
    per_minute *= 10;
  }
  const auto units = static_cast<std::int64_t>(
      std::llround(std::abs(degrees) * 60.0 * static_cast<double>(per_minute)));
  const std::int64_t whole_degrees = units / (60 * per_minute);
  const std::int64_t minute_units = units % (60 * per_minute);
  return append(out, length, "%0*lld%02lld.%0*lld,%c", degree_digits,
                static_cast<long long>(whole_degrees),
                static_cast<long long>(minute_units / per_minute), decimals,
                static_cast<long long>(minute_units % per_minute), hemisphere);
}

// "$" + talker + type, fields appended by the caller, then finish() adds "*hh\r\n".
bool start(std::span<char> out, std::size_t& length, std::string_view talker, const char* type) {
  if (talker.size() != 2) {
    return false;
  }
  length = 0;
  return append(out, length, "$%c%c%s", talker[0], talker[1], type);
}

std::size_t finish(std::span<char> out, std::size_t length) {
  const std::uint8_t sum = checksum(std::span<const char>(out.data() + 1, length - 1));
  if (!append(out, length, "*%02X\r\n", static_cast<unsigned>(sum))) {
    return 0;
  }
  return length;
}

}  // namespace

std::size_t encode_gga(const msg::GpsFix& fix, std::string_view talker,
                       std::span<char> out) noexcept {
  std::size_t length = 0;
  const bool position = fix.has_position && fix.valid;
  const int quality = fix.has_quality ? static_cast<int>(fix.quality) : 0;
  const Precision precision = precision_of(fix);
  const bool ok =
      start(out, length, talker, "GGA") && append_text(out, length, ",") &&
      append_time(out, length, fix) && append_text(out, length, ",") &&
      append_angle(out, length, position, fix.latitude_deg, 2, precision.minute_decimals, 'N',
                   'S') &&
      append_text(out, length, ",") &&
      append_angle(out, length, position, fix.longitude_deg, 3, precision.minute_decimals, 'E',
                   'W') &&
      append(out, length, ",%d,", quality) &&
      (!fix.has_satellites || append(out, length, "%02u", unsigned{fix.satellites_used})) &&
      append_text(out, length, ",") && (!fix.has_hdop || append(out, length, "%.1f", fix.hdop)) &&
      append_text(out, length, ",") &&
      (!(position && fix.has_altitude) ||
       append(out, length, "%.*f", precision.altitude_decimals, fix.altitude_msl_m)) &&
      append_text(out, length, ",M,") &&
      (!fix.has_geoid_separation || append(out, length, "%.1f", fix.geoid_separation_m)) &&
      append_text(out, length, ",M,,");
  return ok ? finish(out, length) : 0;
}

std::size_t encode_rmc(const msg::GpsFix& fix, std::string_view talker,
                       std::span<char> out) noexcept {
  std::size_t length = 0;
  const bool position = fix.has_position && fix.valid;
  const Precision precision = precision_of(fix);
  bool ok = start(out, length, talker, "RMC") && append_text(out, length, ",") &&
            append_time(out, length, fix) && append(out, length, ",%c,", fix.valid ? 'A' : 'V') &&
            append_angle(out, length, position, fix.latitude_deg, 2, precision.minute_decimals, 'N',
                         'S') &&
            append_text(out, length, ",") &&
            append_angle(out, length, position, fix.longitude_deg, 3, precision.minute_decimals,
                         'E', 'W') &&
            append_text(out, length, ",") &&
            (!fix.has_velocity || append(out, length, "%.3f", fix.speed_mps * kKnotsPerMps)) &&
            append_text(out, length, ",") &&
            (!fix.has_course || append(out, length, "%.1f", fix.course_deg)) &&
            append_text(out, length, ",");
  if (ok && fix.has_date) {
    ok = append(out, length, "%02u%02u%02u", unsigned{fix.utc_day}, unsigned{fix.utc_month},
                static_cast<unsigned>(fix.utc_year % 100));
  }
  ok = ok && append(out, length, ",,,%c", fix.valid ? 'A' : 'N');
  return ok ? finish(out, length) : 0;
}

std::size_t encode_gsa(const GsaData& gsa, std::string_view talker, std::span<char> out) noexcept {
  std::size_t length = 0;
  bool ok = start(out, length, talker, "GSA") &&
            append(out, length, ",%c,%u", gsa.automatic ? 'A' : 'M', unsigned{gsa.fix_type});
  const std::size_t listed = std::min<std::size_t>(gsa.satellite_count, 12);
  for (std::size_t i = 0; i < 12 && ok; ++i) {
    ok = i < listed ? append(out, length, ",%02u", unsigned{gsa.satellite_ids[i]})
                    : append_text(out, length, ",");
  }
  const auto dop = [&](bool present, double value) {
    return append_text(out, length, ",") && (!present || append(out, length, "%.1f", value));
  };
  ok = ok && dop(gsa.has_pdop, gsa.pdop) && dop(gsa.has_hdop, gsa.hdop) &&
       dop(gsa.has_vdop, gsa.vdop);
  return ok ? finish(out, length) : 0;
}

}  // namespace blockmap::hal::protocol::nmea
