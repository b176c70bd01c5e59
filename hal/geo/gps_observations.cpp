#include "blockmap/hal/gps_observations.hpp"

#include <algorithm>
#include <chrono>

namespace blockmap::hal {
namespace {

constexpr TimestampNs kDayNs = 86'400 * kNanosecondsPerSecond;
// A delay this far from the smallest one is not a slow line but another clock (the receiver
// set its time, or a date arrived): the delays start over.
constexpr TimestampNs kClockJumpNs = 2 * kNanosecondsPerSecond;

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

localize::GpsCorrection correction_of(msg::GpsFixQuality quality) {
  switch (quality) {
    case msg::GpsFixQuality::kDgps:
      return localize::GpsCorrection::kDifferential;
    case msg::GpsFixQuality::kRtkFixed:
      return localize::GpsCorrection::kRtkFixed;
    case msg::GpsFixQuality::kRtkFloat:
      return localize::GpsCorrection::kRtkFloat;
    default:
      return localize::GpsCorrection::kNone;
  }
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
  const localize::GpsCorrection correction = correction_of(fix.quality);
  const TimestampNs stamp_ns =
      time_ == FixTime::kUtc ? fix_stamp_ns(fix, near_ns) : on_receive_clock(fix);
  out = localize::GpsObservation{stamp_ns, enu.x(), enu.y(), fix.has_hdop ? fix.hdop : 1.0,
                                 correction};
  up_m = enu.z();
  return true;
}

TimestampNs FixConverter::on_receive_clock(const msg::GpsFix& fix) {
  const TimestampNs received_ns = fix.header.stamp_ns;
  // The UTC day nearest to the receipt on the delay known so far (none yet: the same day).
  const TimestampNs utc_ns = fix_stamp_ns(fix, received_ns - best_delay_ns_);
  const TimestampNs delay_ns = received_ns - utc_ns;
  if (delay_count_ > 0 &&
      (delay_ns - best_delay_ns_ > kClockJumpNs || best_delay_ns_ - delay_ns > kClockJumpNs)) {
    delay_count_ = 0;
    ++clock_restarts_;
  }
  delays_ns_[delay_count_ % kDelayWindow] = delay_ns;
  ++delay_count_;
  const std::size_t kept = delay_count_ < kDelayWindow ? delay_count_ : kDelayWindow;
  best_delay_ns_ = delays_ns_[0];
  worst_delay_ns_ = delays_ns_[0];
  for (std::size_t i = 1; i < kept; ++i) {
    best_delay_ns_ = std::min(best_delay_ns_, delays_ns_[i]);
    worst_delay_ns_ = std::max(worst_delay_ns_, delays_ns_[i]);
  }
  return on_pps_edge(utc_ns, utc_ns + best_delay_ns_, received_ns);
}

void FixConverter::on_pps(TimestampNs edge_ns) noexcept {
  pps_edges_ns_[pps_count_ % kPpsEdges] = edge_ns;
  ++pps_count_;
}

TimestampNs FixConverter::on_pps_edge(TimestampNs utc_ns, TimestampNs estimate_ns,
                                      TimestampNs received_ns) {
  const TimestampNs into_second_ns = utc_ns % kNanosecondsPerSecond;
  const std::size_t kept = pps_count_ < kPpsEdges ? pps_count_ : kPpsEdges;
  TimestampNs best_ns = estimate_ns;
  TimestampNs best_gap_ns = kPpsAgreementNs;
  for (std::size_t i = 0; i < kept; ++i) {
    const TimestampNs candidate_ns = pps_edges_ns_[i] + into_second_ns;
    const TimestampNs gap_ns =
        candidate_ns > estimate_ns ? candidate_ns - estimate_ns : estimate_ns - candidate_ns;
    if (gap_ns < best_gap_ns && candidate_ns <= received_ns) {
      best_ns = candidate_ns;
      best_gap_ns = gap_ns;
    }
  }
  if (best_gap_ns < kPpsAgreementNs) {
    ++pps_fixes_;
  }
  return best_ns;
}

}  // namespace blockmap::hal
