// One sweep of a 2D laser scanner, with a capacity fixed at compile time so that scans can
// live in rings and queues without allocation.
#pragma once

#include <array>
#include <cstdint>

#include "blockmap/msg/header.hpp"

namespace blockmap::msg {

// Enough for every supported scanner: SICK LMS2xx 401, TiM5xx 811, Hokuyo UTM-30LX 1081,
// LMS5xx at 1/6 degree over 190 degrees 1141.
inline constexpr std::size_t kMaxLaserBeams = 1141;

enum class BeamStatus : std::uint8_t {
  kValid = 0,
  kNoReturn,     // nothing within range (the device's "max range" or "no echo" code)
  kDazzled,      // blinded by sunlight or another light source
  kDeviceError,  // the device flagged this value as an error (overflow, low SNR, read error)
  kTooClose,     // below the device's minimum range
};

// Beam i points at start_angle_rad + i * angle_increment_rad in the scanner's frame
// (x forward, y left, counter-clockwise positive). The sweep of beam i started
// i * time_increment_s after header.stamp_ns minus the device layer's latency correction.
struct LaserScan {
  Header header;
  double start_angle_rad = 0.0;
  double angle_increment_rad = 0.0;
  double time_increment_s = 0.0;  // between consecutive beams; 0 when unknown
  double scan_period_s = 0.0;     // between consecutive scans; 0 when unknown
  double range_min_m = 0.0;
  double range_max_m = 0.0;
  std::uint32_t scan_counter = 0;  // the device's own scan number or timestamp, when it has one
  std::uint16_t beam_count = 0;
  bool has_intensities = false;
  std::array<float, kMaxLaserBeams> ranges_m{};
  std::array<float, kMaxLaserBeams> intensities{};  // device units (RSSI, reflectivity)
  std::array<BeamStatus, kMaxLaserBeams> status{};
};

}  // namespace blockmap::msg
