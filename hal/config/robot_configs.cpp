// What the device layer and the mapper are configured with for a robot's description.
#include <algorithm>

#include "blockmap/hal/config/robot.hpp"

namespace blockmap::hal::config {

namespace lms = protocol::sick_lms2xx;

devices::SegwayBaseConfig segway_base_config_for(const RobotSpec& robot) {
  devices::SegwayBaseConfig config;
  config.rmp.model = robot.base.model;
  config.rmp.yaw_sign = robot.base.yaw_sign;
  config.track_m = robot.base.track_m;
  return config;
}

// The device layer's view of a laser: its codec, and its timing when one mirror turn makes a
// scan (the interlaced 0.5 and 0.25 deg variants sweep over several turns, in an order the
// telegram does not give: their beams keep the scan's stamp).
devices::Lms2xxScannerConfig lms2xx_config_for(const LaserSpec& spec) {
  const lms::VariantGeometry geometry = lms::geometry(spec.variant);
  const bool single_turn = spec.variant == lms::AngularVariant::k180Deg1Deg ||
                           spec.variant == lms::AngularVariant::k100Deg1Deg;
  devices::Lms2xxScannerConfig config;
  if (single_turn) {
    config = devices::lms2xx_single_turn_timing(geometry.field_deg,
                                                geometry.resolution_centideg / 100.0);
  }
  config.codec.range_bits = spec.range_bits;
  config.codec.variant = spec.variant;
  return config;
}

pipeline::MapperConfig mapper_config_for(const RobotSpec& robot) {
  pipeline::MapperConfig config;
  config.localizer.antenna_m = robot.gps.antenna_m;
  config.laser_count = std::min(robot.lasers.size(), pipeline::kMaxLasers);
  // An LMS2xx scan has at most 401 beams (100 deg at 0.25 deg); a TiM's telegram says.
  constexpr std::size_t kLms2xxMaxBeams = 401;
  config.max_beams = kLms2xxMaxBeams;
  config.scans_per_s = 0.0;
  // The robot's wheels say where the ground is, so the ground far from the lasers can stay out
  // of the window (ScanProjectorConfig says why; docs/mapper.md, Speed): 8 m keeps
  // the dense ground near the robot, which makes the ground's plane, and halves benning's
  // window. `[projection] far_ground_range_m = 0` keeps every ground return.
  config.projection.axle_height_m = robot.base.wheel_radius_m;
  config.projection.far_ground_range_m = 8.0;
  for (std::size_t i = 0; i < config.laser_count; ++i) {
    const LaserSpec& laser = robot.lasers[i];
    config.laser_mounts[i] = laser.mount;
    if (laser.protocol != LaserProtocol::kLms2xx) {
      config.max_beams = msg::kMaxLaserBeams;
    }
    config.scans_per_s += laser.scan_rate_hz;  // at most one scan per mirror turn
  }
  return config;
}

}  // namespace blockmap::hal::config
