// A laser scan as the mapper keeps it while it waits for its pose: two bytes per beam
// instead of nine. With a pose lag (LocalizerConfig::map_pose_lag_s) the mapper holds tens of
// seconds of scans, 4,500 of them at 30 s for two LMS291: 46 MB as msg::LaserScan, 3.6 MB
// like this.
//
// A beam is a code: a valid range in whole units of unit_m (1 mm, else 1 cm when the scan
// reaches beyond 65 m), or kInvalidCode + its status. The unit is chosen so that the ranges
// come back bit for bit where the device measures in millimetres or centimetres (LMS2xx,
// Hokuyo); a range that no unit gives back exactly (a TiM's scaled values) is rounded to the
// millimetre, well inside any of these lasers' accuracy. Intensities are not kept: the
// projection does not use them.
#pragma once

#include <cstdint>
#include <span>

#include "blockmap/core/time.hpp"
#include "blockmap/msg/laser_scan.hpp"

namespace blockmap::pipeline {

struct CompactScanHeader {
  msg::Header header;
  TimestampNs last_beam_ns = 0;  // when the scan's last beam was measured
  double start_angle_rad = 0.0;
  double angle_increment_rad = 0.0;
  double time_increment_s = 0.0;
  double scan_period_s = 0.0;
  double range_min_m = 0.0;
  double range_max_m = 0.0;
  double unit_m = 0.001;
  std::uint32_t scan_counter = 0;
  std::uint16_t beam_count = 0;
  std::uint16_t rounded_beams = 0;  // valid ranges that no unit gave back exactly
};

inline constexpr std::uint16_t kInvalidCode = 0xFFF8;  // + msg::BeamStatus (1..4)

// False (nothing written) when the scan has more beams than `codes` holds.
[[nodiscard]] bool compact_scan(const msg::LaserScan& scan, CompactScanHeader& header,
                                std::span<std::uint16_t> codes) noexcept;
void expand_scan(const CompactScanHeader& header, std::span<const std::uint16_t> codes,
                 msg::LaserScan& out) noexcept;

}  // namespace blockmap::pipeline
