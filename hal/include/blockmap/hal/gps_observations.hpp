// GPS fixes as the localizer takes them: NMEA's UTC of day on the run's clock, the geodetic
// position in the local ENU frame (anchored at a configured origin or the first good fix),
// and whether the receiver had a differential correction. Shared by `run` and `replay`
// and by the simulated robot.
#pragma once

#include <cstddef>
#include <optional>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/msg/gps_fix.hpp"

namespace blockmap::hal {

// The fix's UTC on the log's clock. With a date (RMC), exact; without one (GGA alone), the day
// that puts it nearest to `near_ns` (the odometry's time), which survives midnight.
[[nodiscard]] TimestampNs fix_stamp_ns(const msg::GpsFix& fix, TimestampNs near_ns);

// The fix's ellipsoidal position (NMEA gives the height above the geoid and its separation).
[[nodiscard]] GeodeticPoint fix_point(const msg::GpsFix& fix);

class FixConverter {
 public:
  FixConverter() = default;
  explicit FixConverter(const GeodeticPoint& origin) : frame_(origin) {}

  // A usable fix (valid, with position and time) becomes an observation and its height in
  // the local frame; false (counted) otherwise.
  bool convert(const msg::GpsFix& fix, TimestampNs near_ns, localize::GpsObservation& out,
               double& up_m);
  [[nodiscard]] const std::optional<LocalEnuFrame>& frame() const noexcept { return frame_; }
  [[nodiscard]] std::size_t without_position() const noexcept { return without_position_; }

 private:
  std::optional<LocalEnuFrame> frame_;
  std::size_t without_position_ = 0;
};

}  // namespace blockmap::hal
