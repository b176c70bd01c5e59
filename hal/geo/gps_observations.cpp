#include "blockmap/hal/gps_observations.hpp"

#include <chrono>

namespace blockmap::hal {
namespace {

constexpr TimestampNs kDayNs = 86'400 * kNanosecondsPerSecond;

}  // namespace

TimestampNs fix_stamp_ns(const msg::GpsFix& fix, TimestampNs near_ns) {
  const TimestampNs of_day_ns = static_cast<TimestampNs>(fix.utc_milliseconds_of_day) * 1'000'000;
  if (fix.has_date) {
    const std::chrono::sys_days day = std::chrono::year_month_day(std::chrono::year(fix.utc_year),
                                                                  std::chrono::month(fix.utc_month),
                                                                  std::chrono::day(fix.utc_day));
    return static_cast<TimestampNs>(day.time_since_epoch().count()) * kDayNs + of_day_ns;
  }
  const TimestampNs day_start = near_ns - near_ns % kDayNs;
  TimestampNs stamp = day_start + of_day_ns;
  if (stamp - near_ns > kDayNs / 2) {
    stamp -= kDayNs;
  } else if (near_ns - stamp > kDayNs / 2) {
    stamp += kDayNs;
  }
  return stamp;
}

GeodeticPoint fix_point(const msg::GpsFix& fix) {
  return {fix.latitude_deg, fix.longitude_deg,
          fix.altitude_msl_m + (fix.has_geoid_separation ? fix.geoid_separation_m : 0.0)};
}

bool FixConverter::convert(const msg::GpsFix& fix, TimestampNs near_ns,
                           localize::GpsObservation& out, double& up_m) {
  if (!fix.valid || !fix.has_position || !fix.has_time) {
    ++without_position_;
    return false;
  }
  if (!frame_) {
    frame_.emplace(fix_point(fix));  // the local frame: anchored at the first good fix
  }
  const Eigen::Vector3d enu = frame_->to_enu_m(fix_point(fix));
  const bool differential = fix.quality == msg::GpsFixQuality::kDgps ||
                            fix.quality == msg::GpsFixQuality::kRtkFixed ||
                            fix.quality == msg::GpsFixQuality::kRtkFloat;
  out = localize::GpsObservation{fix_stamp_ns(fix, near_ns), enu.x(), enu.y(),
                                 fix.has_hdop ? fix.hdop : 1.0, differential};
  up_m = enu.z();
  return true;
}

}  // namespace blockmap::hal
