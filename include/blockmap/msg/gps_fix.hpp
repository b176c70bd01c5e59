// A GNSS position fix, as decoded from the receiver (NMEA GGA/RMC/GLL/GNS), before any
// conversion to the local frame.
#pragma once

#include <cstdint>

#include "blockmap/msg/header.hpp"

namespace blockmap::msg {

enum class GpsFixQuality : std::uint8_t {
  kInvalid = 0,
  kGps = 1,
  kDgps = 2,
  kPps = 3,
  kRtkFixed = 4,
  kRtkFloat = 5,
  kEstimated = 6,
  kManual = 7,
  kSimulated = 8,
};

enum class GpsFixMode : std::uint8_t { kUnknown = 0, kNone, k2d, k3d };

// Fields a sentence did not carry are flagged absent, never zero: receivers leave them empty
// (or zero-filled) when they have no fix, and a zero latitude is a real place.
struct GpsFix {
  Header header;
  // UTC of the fix from the receiver.
  bool has_time = false;
  std::int32_t utc_milliseconds_of_day = 0;
  bool has_date = false;
  std::uint16_t utc_year = 0;
  std::uint8_t utc_month = 0;
  std::uint8_t utc_day = 0;

  bool has_position = false;
  double latitude_deg = 0.0;   // WGS-84, north positive
  double longitude_deg = 0.0;  // WGS-84, east positive
  bool has_altitude = false;
  double altitude_msl_m = 0.0;
  bool has_geoid_separation = false;
  double geoid_separation_m = 0.0;  // geoid above the ellipsoid; h_ellipsoid = msl + separation

  bool has_quality = false;
  GpsFixQuality quality = GpsFixQuality::kInvalid;
  GpsFixMode mode = GpsFixMode::kUnknown;
  bool has_satellites = false;
  std::uint8_t satellites_used = 0;
  bool has_hdop = false;
  double hdop = 0.0;

  bool has_velocity = false;
  double speed_mps = 0.0;
  bool has_course = false;
  double course_deg = 0.0;  // over ground, true north, clockwise

  // False when the receiver itself flags the fix invalid (GGA quality 0, RMC/GLL status V).
  bool valid = false;
};

}  // namespace blockmap::msg
