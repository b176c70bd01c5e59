#include "blockmap/hal/sim/motion.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/localize/localizer.hpp"

namespace blockmap::hal::sim {
namespace {}  // namespace

Eigen::Matrix3d RobotState::rotation() const {
  return localize::attitude_rotation(roll_rad, pitch_rad, yaw_rad);
}

RobotMotion::RobotMotion(const config::BaseSpec& base, const Path& path, const Terrain& terrain)
    : base_(base), terrain_(terrain), waypoints_(path.waypoints_m) {
  BLOCKMAP_CHECK_MSG(waypoints_.size() >= 2, "a path needs two waypoints");
  cumulative_m_.push_back(0.0);
  for (std::size_t i = 1; i < waypoints_.size(); ++i) {
    cumulative_m_.push_back(cumulative_m_.back() + (waypoints_[i] - waypoints_[i - 1]).norm());
  }
  RobotState& start = history_[0];
  const Vec2 heading = waypoints_[1] - waypoints_[0];
  start.yaw_rad = std::atan2(heading.y(), heading.x());
  start.position_m = Vec3(waypoints_[0].x(), waypoints_[0].y(), 0.0);
  settle_on_ground(start);
  count_ = 1;
  cruise_speed_mps_ = path.cruise_speed_mps;
}

void RobotMotion::settle_on_ground(RobotState& state) const noexcept {
  const Vec2 left(-std::sin(state.yaw_rad), std::cos(state.yaw_rad));
  const Vec2 centre = state.position_m.head<2>();
  const Vec2 l = centre + left * (base_.track_m / 2);
  const Vec2 r = centre - left * (base_.track_m / 2);
  const double ground_left = terrain_.height_m(l.x(), l.y());
  const double ground_right = terrain_.height_m(r.x(), r.y());
  state.position_m.z() = 0.5 * (ground_left + ground_right) + base_.wheel_radius_m;
  state.roll_rad = std::atan2(ground_left - ground_right, base_.track_m);
}

Vec2 RobotMotion::point_at(double s_m) const noexcept {
  s_m = std::clamp(s_m, 0.0, cumulative_m_.back());
  std::size_t i = segment_;
  while (i + 2 < cumulative_m_.size() && cumulative_m_[i + 1] < s_m) {
    ++i;
  }
  const double length = cumulative_m_[i + 1] - cumulative_m_[i];
  const double f = length > 0.0 ? (s_m - cumulative_m_[i]) / length : 0.0;
  return waypoints_[i] + f * (waypoints_[i + 1] - waypoints_[i]);
}

double RobotMotion::project(const Vec2& p) const noexcept {
  // Search the current segment and the next ones within a few metres: never back, never far.
  double best_s = progress_m_;
  double best_d = std::numeric_limits<double>::max();
  for (std::size_t i = segment_; i + 1 < waypoints_.size(); ++i) {
    if (cumulative_m_[i] > progress_m_ + 3.0 * base_.lookahead_m) {
      break;
    }
    const Vec2 a = waypoints_[i];
    const Vec2 ab = waypoints_[i + 1] - a;
    const double f = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const double d = (a + f * ab - p).squaredNorm();
    const double s = cumulative_m_[i] + f * ab.norm();
    if (d < best_d - 1e-9 && s >= progress_m_ - 0.5) {
      best_d = d;
      best_s = s;
    }
  }
  return std::max(best_s, progress_m_);
}

void RobotMotion::step() noexcept {
  const RobotState& now = history_[latest_index_];
  RobotState next = now;
  next.t_s = now.t_s + kStepS;
  const Vec2 position = now.position_m.head<2>();

  // Where to go: pure pursuit towards the path point one lookahead ahead.
  progress_m_ = project(position);
  while (segment_ + 2 < cumulative_m_.size() && cumulative_m_[segment_ + 1] < progress_m_) {
    ++segment_;
  }
  const double remaining_m = cumulative_m_.back() - progress_m_;
  const Vec2 target = point_at(progress_m_ + base_.lookahead_m);
  const Vec2 to_target = target - position;
  const double alpha = wrap_angle(std::atan2(to_target.y(), to_target.x()) - now.yaw_rad);
  const double distance = std::max(to_target.norm(), 0.3);
  const double curvature = 2.0 * std::sin(alpha) / distance;

  // How fast: cruise, slower in turns, stopping at the end.
  double speed_demand = cruise_speed_mps_;
  if (std::abs(curvature) > 1e-6) {
    speed_demand =
        std::min({speed_demand, std::sqrt(base_.max_lateral_accel_mps2 / std::abs(curvature)),
                  base_.max_yaw_rate_radps / std::abs(curvature)});
  }
  speed_demand = std::min(speed_demand, std::sqrt(2.0 * base_.max_decel_mps2 * remaining_m));
  if (std::abs(alpha) > std::numbers::pi / 2) {
    speed_demand = std::min(speed_demand, 0.3);  // turning on the spot, nearly
  }
  const double accel = std::clamp((speed_demand - now.speed_mps) / kStepS, -base_.max_decel_mps2,
                                  base_.max_accel_mps2);
  next.accel_mps2 = accel;
  next.speed_mps = std::max(0.0, now.speed_mps + accel * kStepS);
  double yaw_rate =
      std::clamp(next.speed_mps * curvature, -base_.max_yaw_rate_radps, base_.max_yaw_rate_radps);
  if (next.speed_mps < 0.05 && std::abs(alpha) > 0.3 && remaining_m > 0.5) {
    yaw_rate = std::copysign(base_.max_yaw_rate_radps * 0.5, alpha);  // the RMP turns in place
  }
  next.yaw_rate_radps = yaw_rate;
  next.yaw_rad = wrap_angle(now.yaw_rad + yaw_rate * kStepS);
  const double mean_speed = 0.5 * (now.speed_mps + next.speed_mps);
  const double mid_yaw = now.yaw_rad + 0.5 * yaw_rate * kStepS;
  next.position_m.x() += mean_speed * std::cos(mid_yaw) * kStepS;
  next.position_m.y() += mean_speed * std::sin(mid_yaw) * kStepS;
  next.left_wheel_m += (mean_speed - yaw_rate * base_.track_m / 2) * kStepS;
  next.right_wheel_m += (mean_speed + yaw_rate * base_.track_m / 2) * kStepS;
  distance_m_ += mean_speed * kStepS;
  settle_on_ground(next);
  next.roll_rate_radps = (next.roll_rad - now.roll_rad) / kStepS;

  // Pitch: the RMP leans into its acceleration; climbing a bump tips it back. A damped
  // second-order response (semi-implicit Euler) with the configured frequency and damping.
  const Vec2 forward(std::cos(next.yaw_rad), std::sin(next.yaw_rad));
  const Vec2 ahead = next.position_m.head<2>() + 0.1 * forward;
  const Vec2 behind = next.position_m.head<2>() - 0.1 * forward;
  const double slope =
      (terrain_.height_m(ahead.x(), ahead.y()) - terrain_.height_m(behind.x(), behind.y())) / 0.2;
  const double pitch_demand =
      base_.pitch_per_accel_rad_per_mps2 * accel - base_.bump_pitch_gain * slope;
  const double omega = 2.0 * std::numbers::pi * base_.pitch_natural_frequency_hz;
  const double pitch_accel = omega * omega * (pitch_demand - now.pitch_rad) -
                             2.0 * base_.pitch_damping_ratio * omega * now.pitch_rate_radps;
  next.pitch_rate_radps = now.pitch_rate_radps + pitch_accel * kStepS;
  next.pitch_rad = now.pitch_rad + next.pitch_rate_radps * kStepS;

  finished_ = remaining_m < 0.1 && next.speed_mps < 0.01;
  latest_index_ = (latest_index_ + 1) % kHistory;
  history_[latest_index_] = next;
  count_ = std::min(count_ + 1, kHistory);
}

void RobotMotion::advance_to(double t_s) noexcept {
  while (history_[latest_index_].t_s < t_s) {
    step();
  }
}

RobotState RobotMotion::state_at(double t_s) const {
  const std::size_t oldest = (latest_index_ + kHistory + 1 - count_) % kHistory;
  BLOCKMAP_CHECK_MSG(
      t_s >= history_[oldest].t_s - 1e-9 && t_s <= history_[latest_index_].t_s + 1e-9,
      "state_at: time outside the kept history");
  // States are kStepS apart: index arithmetic, no search.
  const double offset = (t_s - history_[oldest].t_s) / kStepS;
  const auto steps = std::min(static_cast<std::size_t>(std::max(offset, 0.0)), count_ - 1);
  const RobotState& a = history_[(oldest + steps) % kHistory];
  if (steps + 1 >= count_) {
    return a;
  }
  const RobotState& b = history_[(oldest + steps + 1) % kHistory];
  const double f = std::clamp((t_s - a.t_s) / kStepS, 0.0, 1.0);
  RobotState s = a;
  s.t_s = t_s;
  s.position_m = a.position_m + f * (b.position_m - a.position_m);
  s.roll_rad = a.roll_rad + f * (b.roll_rad - a.roll_rad);
  s.pitch_rad = a.pitch_rad + f * (b.pitch_rad - a.pitch_rad);
  s.yaw_rad = a.yaw_rad + f * wrap_angle(b.yaw_rad - a.yaw_rad);
  s.speed_mps = a.speed_mps + f * (b.speed_mps - a.speed_mps);
  s.accel_mps2 = b.accel_mps2;
  s.yaw_rate_radps = b.yaw_rate_radps;
  s.pitch_rate_radps = a.pitch_rate_radps + f * (b.pitch_rate_radps - a.pitch_rate_radps);
  s.roll_rate_radps = b.roll_rate_radps;
  s.left_wheel_m = a.left_wheel_m + f * (b.left_wheel_m - a.left_wheel_m);
  s.right_wheel_m = a.right_wheel_m + f * (b.right_wheel_m - a.right_wheel_m);
  return s;
}

}  // namespace blockmap::hal::sim
