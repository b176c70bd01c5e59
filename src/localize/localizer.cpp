#include "blockmap/localize/localizer.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"

namespace blockmap::localize {

Eigen::Matrix3d attitude_rotation(double roll_rad, double pitch_rad, double yaw_rad) noexcept {
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

std::string validate(const LocalizerConfig& config) {
  std::string problem = validate(config.filter);
  if (!problem.empty()) {
    return problem;
  }
  if (!(config.height_smoothing_s >= 0.0) || !(config.rtk_height_smoothing_s >= 0.0) ||
      !(config.max_speed_mps > 0.0)) {
    return "height_smoothing_s and rtk_height_smoothing_s must be >= 0 and max_speed_mps > 0";
  }
  if (!config.antenna_m.allFinite()) {
    return "antenna_m must be finite";
  }
  if (!(config.map_pose_smoothing_s >= 0.0) || !(config.rtk_map_pose_smoothing_s >= 0.0) ||
      !(config.map_pose_snap_m > 0.0) || !(config.map_pose_start_heading_spread_rad > 0.0) ||
      !(config.map_pose_snap_rad > 0.0) || config.map_pose_capacity < 2) {
    return "map_pose_smoothing_s and rtk_map_pose_smoothing_s must be >= 0, map_pose_snap_m, "
           "map_pose_snap_rad and map_pose_start_heading_spread_rad > 0, and map_pose_capacity "
           "at least 2";
  }
  const double window_s =
      static_cast<double>(config.filter.history_steps) * config.filter.history_interval_s;
  if (!(config.map_pose_lag_s >= 0.0) || config.map_pose_lag_s + 2.0 > window_s ||
      config.map_pose_lag_samples < 2) {
    return "map_pose_lag_s must be >= 0 and 2 s shorter than the filter's window "
           "(history_steps x history_interval_s), and map_pose_lag_samples at least 2";
  }
  return {};
}

void Localizer::init(Arena& arena, const LocalizerConfig& config) {
  BLOCKMAP_CHECK_MSG(validate(config).empty(), "invalid localizer configuration");
  config_ = config;
  filter_.init(arena, config.filter);
  // One more than the filter's history: a recovery may push a step at a stamp already kept.
  attitudes_ =
      arena.allocate_array<Attitude>(config.filter.history_steps + 1, "localize.localizer");
  scratch_ = arena.allocate_array<Pose2>(config.filter.history_steps, "localize.localizer");
  map_poses_ = arena.allocate_array<Pose3>(config.map_pose_capacity, "localize.map_poses");
  odometry_poses_ = arena.allocate_array<Pose2>(config.map_pose_capacity, "localize.map_poses");
  if (config.map_pose_lag_s > 0.0) {
    lagged_ = arena.allocate_array<BaseMotion>(config.map_pose_lag_samples, "localize.map_poses");
  }
}

std::size_t Localizer::arena_bytes(const LocalizerConfig& config) noexcept {
  constexpr std::size_t kAlignment = Arena::kMaxPaddingBytes;
  return ParticleFilter::arena_bytes(config.filter) +
         (config.filter.history_steps + 1) * sizeof(Attitude) +
         config.filter.history_steps * sizeof(Pose2) +
         config.map_pose_capacity * (sizeof(Pose3) + sizeof(Pose2)) +
         (config.map_pose_lag_s > 0.0 ? config.map_pose_lag_samples * sizeof(BaseMotion) : 0) +
         4 * kAlignment;
}

std::size_t Localizer::memory_bytes() const noexcept {
  return filter_.memory_bytes() + attitudes_.size_bytes() + scratch_.size_bytes() +
         map_poses_.size_bytes() + odometry_poses_.size_bytes() + lagged_.size_bytes();
}

void Localizer::on_base(const msg::OdometrySample& odometry, const msg::ImuSample& imu) noexcept {
  const TimestampNs stamp_ns = odometry.header.stamp_ns;
  if (have_base_ && stamp_ns < last_base_ns_) {
    ++counters_.stale_samples;
    return;
  }
  ++counters_.base_samples;
  roll_rad_ = imu.roll_rad;
  pitch_rad_ = imu.pitch_rad;
  double distance_m = 0.0;
  if (have_base_) {
    distance_m = odometry.fore_aft_distance_m - last_fore_aft_m_;
    const double dt_s = seconds_from_ns(stamp_ns - last_base_ns_);
    if (std::abs(distance_m) > config_.max_speed_mps * dt_s + 0.01) {
      ++counters_.odometry_jumps;  // the integrators were reset: start counting from here
      distance_m = 0.0;
    }
  }
  have_base_ = true;
  last_base_ns_ = stamp_ns;
  last_fore_aft_m_ = odometry.fore_aft_distance_m;
  if (!filter_.started() && config_.start_at_known_pose) {
    Pose2 start = config_.start_pose;
    start.stamp_ns = stamp_ns;
    filter_.start_at_pose(start, config_.start_position_sigma_m, config_.start_yaw_sigma_rad);
  }
  filter_.predict(stamp_ns, distance_m, imu.yaw_rate_radps);
  record_if_stepped();
  const BaseMotion motion{stamp_ns,  distance_m, imu.yaw_rate_radps,
                          height_m_, roll_rad_,  pitch_rad_};
  if (lagged_.empty()) {
    advance_map_pose(motion);
    return;
  }
  if (lagged_count_ == lagged_.size()) {
    ++counters_.lag_forced;
    advance_lagged_one();
  }
  lagged_[(lagged_first_ + lagged_count_) % lagged_.size()] = motion;
  ++lagged_count_;
  advance_lagged_map_pose(stamp_ns - ns_from_seconds(config_.map_pose_lag_s));
}

GpsOutcome Localizer::on_fix(const GpsObservation& fix, double up_m) noexcept {
  // The antenna's mount turned by the base's pitch and roll: the filter turns it by each
  // particle's heading.
  const Eigen::Vector3d antenna_m =
      attitude_rotation(roll_rad_, pitch_rad_, 0.0) * config_.antenna_m;
  antenna_fix_ = fix;
  antenna_fix_.antenna_ahead_m = antenna_m.x();
  antenna_fix_.antenna_left_m = antenna_m.y();
  const GpsOutcome outcome = filter_.update(antenna_fix_);
  if (outcome != GpsOutcome::kRejected) {
    follow_height(fix, up_m - antenna_m.z());
    if (carrier_phase(fix.correction)) {
      have_carrier_phase_fix_ = true;
      last_carrier_phase_fix_ns_ = std::max(last_carrier_phase_fix_ns_, fix.stamp_ns);
    } else {
      last_code_fix_ns_ = std::max(last_code_fix_ns_, fix.stamp_ns);
    }
  }
  record_if_stepped();
  if (outcome != GpsOutcome::kRejected && lagged_.empty() && filter_.started()) {
    pull_map_pose(filter_.estimate(),
                  BaseMotion{last_base_ns_, 0.0, 0.0, height_m_, roll_rad_, pitch_rad_});
  }
  return outcome;
}

GpsObservation Localizer::last_robot_fix() const noexcept {
  // For the whole run's path, which takes fixes of the robot frame.
  const double yaw_rad = filter_.started() ? filter_.estimate().yaw_rad : 0.0;
  const double c = std::cos(yaw_rad);
  const double s = std::sin(yaw_rad);
  GpsObservation robot = antenna_fix_;
  robot.east_m -= c * antenna_fix_.antenna_ahead_m - s * antenna_fix_.antenna_left_m;
  robot.north_m -= s * antenna_fix_.antenna_ahead_m + c * antenna_fix_.antenna_left_m;
  robot.antenna_ahead_m = 0.0;
  robot.antenna_left_m = 0.0;
  return robot;
}

bool Localizer::carrier_phase_holds(TimestampNs stamp_ns) const noexcept {
  return have_carrier_phase_fix_ && last_carrier_phase_fix_ns_ > last_code_fix_ns_ &&
         stamp_ns - last_carrier_phase_fix_ns_ <= kCarrierPhaseHoldNs;
}

void Localizer::follow_height(const GpsObservation& fix, double height_m) noexcept {
  // The robot frame's height: the first fix's, then followed within about a second of a
  // carrier-phase fix; a code fix's is left out (level) or low-passed over minutes.
  const bool centimetres = carrier_phase(fix.correction);
  if (!have_height_) {
    height_m_ = height_m;
    have_height_ = true;
  } else if (centimetres || !config_.level_with_code_fixes) {
    const double smoothing_s =
        centimetres ? config_.rtk_height_smoothing_s : config_.height_smoothing_s;
    const double dt_s = std::max(0.0, seconds_from_ns(fix.stamp_ns - last_height_ns_));
    height_m_ += (height_m - height_m_) * dt_s / (smoothing_s + dt_s);
  }
  last_height_ns_ = fix.stamp_ns;
}

void Localizer::advance_lagged_map_pose(TimestampNs until_ns) noexcept {
  while (lagged_count_ > 0 && lagged_[lagged_first_].stamp_ns <= until_ns) {
    advance_lagged_one();
  }
}

void Localizer::flush_map_pose(TimestampNs until_ns) noexcept {
  TimestampNs horizon_ns = 0;
  while (lagged_count_ > 0 && (!map_pose_horizon(horizon_ns) || horizon_ns < until_ns)) {
    advance_lagged_one();
  }
}

void Localizer::advance_lagged_one() noexcept {
  const BaseMotion motion = lagged_[lagged_first_];
  lagged_first_ = (lagged_first_ + 1) % lagged_.size();
  --lagged_count_;
  if (!filter_.started()) {
    return;
  }
  // The smoothed path at this sample's time, once per history step: the pose the fixes
  // since then agree on.
  const bool pull_due = !map_started_ || seconds_from_ns(motion.stamp_ns - last_pull_ns_) >=
                                             config_.filter.history_interval_s;
  if (map_started_) {
    advance_map_pose(motion);
  }
  Pose2 smoothed;
  if (pull_due && filter_.pose_at(motion.stamp_ns, smoothed)) {
    pull_map_pose(smoothed, motion);
    last_pull_ns_ = motion.stamp_ns;
  }
}

void Localizer::advance_map_pose(const BaseMotion& motion) noexcept {
  if (!filter_.started()) {
    return;
  }
  if (!map_started_) {
    pull_map_pose(filter_.estimate(), motion);  // starts at the estimate
    return;
  }
  // Dead reckoning with the filter's calibration of the odometry, at the mid-step heading.
  const double dt_s = std::max(0.0, seconds_from_ns(motion.stamp_ns - map_pose_.stamp_ns));
  const double turn_rad = (motion.yaw_rate_radps - yaw_rate_bias_radps_) * dt_s;
  const double heading_rad = map_pose_.yaw_rad + 0.5 * turn_rad;
  const double travel_m = motion.distance_m * distance_scale_;
  map_pose_.x_m += travel_m * std::cos(heading_rad);
  map_pose_.y_m += travel_m * std::sin(heading_rad);
  map_pose_.yaw_rad = wrap_angle(map_pose_.yaw_rad + turn_rad);
  // The odometry's own pose: the wheels and the gyroscope as they report, uncalibrated (the
  // scan matcher learns its own gyroscope bias; the filter's, learnt from fixes, lags by
  // minutes and would bend the matched path while it settles).
  const double raw_turn_rad = motion.yaw_rate_radps * dt_s;
  const double odometry_heading_rad = odometry_pose_.yaw_rad + 0.5 * raw_turn_rad;
  odometry_pose_.x_m += motion.distance_m * std::cos(odometry_heading_rad);
  odometry_pose_.y_m += motion.distance_m * std::sin(odometry_heading_rad);
  odometry_pose_.yaw_rad = wrap_angle(odometry_pose_.yaw_rad + raw_turn_rad);
  // The share of the correction due in dt (an exponential approach to the estimate).
  const double smoothing_s = carrier_phase_holds(motion.stamp_ns) ? config_.rtk_map_pose_smoothing_s
                                                                  : config_.map_pose_smoothing_s;
  const double share = smoothing_s > 0.0 ? std::min(1.0, dt_s / smoothing_s) : 1.0;
  map_pose_.x_m += share * pending_x_m_;
  map_pose_.y_m += share * pending_y_m_;
  map_pose_.yaw_rad = wrap_angle(map_pose_.yaw_rad + share * pending_yaw_rad_);
  pending_x_m_ -= share * pending_x_m_;
  pending_y_m_ -= share * pending_y_m_;
  pending_yaw_rad_ -= share * pending_yaw_rad_;
  map_pose_.stamp_ns = motion.stamp_ns;
  keep_map_pose(motion);
}

void Localizer::pull_map_pose(const Pose2& target, const BaseMotion& motion) noexcept {
  if (!map_started_ && carrier_phase_holds(target.stamp_ns) &&
      !(filter_.heading_spread_rad() <= config_.map_pose_start_heading_spread_rad)) {
    return;  // the heading is not known yet
  }
  distance_scale_ = filter_.mean_distance_scale();
  yaw_rate_bias_radps_ = filter_.mean_yaw_rate_bias_radps();
  const double gap_x_m = target.x_m - map_pose_.x_m;
  const double gap_y_m = target.y_m - map_pose_.y_m;
  const double gap_yaw_rad = wrap_angle(target.yaw_rad - map_pose_.yaw_rad);
  const bool snap = !map_started_ || std::hypot(gap_x_m, gap_y_m) > config_.map_pose_snap_m ||
                    std::abs(gap_yaw_rad) > config_.map_pose_snap_rad;
  if (!snap) {
    pending_x_m_ = gap_x_m;
    pending_y_m_ = gap_y_m;
    pending_yaw_rad_ = gap_yaw_rad;
    return;
  }
  if (map_started_) {
    ++counters_.map_pose_snaps;
    snap_stamps_[snap_next_] = target.stamp_ns;
    snap_next_ = (snap_next_ + 1) % snap_stamps_.size();
    snap_count_ = std::min(snap_count_ + 1, snap_stamps_.size());
  }
  if (!map_started_) {
    odometry_pose_ = target;  // dead reckoning from the first estimate on, never pulled
  }
  map_started_ = true;
  map_pose_.stamp_ns = target.stamp_ns;
  map_pose_.x_m = target.x_m;
  map_pose_.y_m = target.y_m;
  map_pose_.yaw_rad = target.yaw_rad;
  pending_x_m_ = 0.0;
  pending_y_m_ = 0.0;
  pending_yaw_rad_ = 0.0;
  keep_map_pose(motion);
}

bool Localizer::map_pose_snapped_between(TimestampNs after_ns,
                                         TimestampNs until_ns) const noexcept {
  for (std::size_t i = 0; i < snap_count_; ++i) {
    if (snap_stamps_[i] > after_ns && snap_stamps_[i] <= until_ns) {
      return true;
    }
  }
  return false;
}

void Localizer::keep_map_pose(const BaseMotion& motion) noexcept {
  // With the attitude and height of this sample (the base pitches at 1-2 Hz: the filter's
  // history steps, 4 Hz, would alias it).
  map_pose_.z_m = motion.z_m;
  map_pose_.roll_rad = motion.roll_rad;
  map_pose_.pitch_rad = motion.pitch_rad;
  if (map_count_ > 0) {
    Pose3& newest = map_poses_[(map_first_ + map_count_ - 1) % map_poses_.size()];
    if (newest.stamp_ns == map_pose_.stamp_ns) {
      newest = map_pose_;  // a snap at the stamp of the last sample replaces it
      odometry_poses_[(map_first_ + map_count_ - 1) % map_poses_.size()] = odometry_pose_;
      return;
    }
  }
  if (map_count_ == map_poses_.size()) {
    map_first_ = (map_first_ + 1) % map_poses_.size();
    --map_count_;
  }
  map_poses_[(map_first_ + map_count_) % map_poses_.size()] = map_pose_;
  odometry_pose_.stamp_ns = map_pose_.stamp_ns;
  odometry_poses_[(map_first_ + map_count_) % map_poses_.size()] = odometry_pose_;
  ++map_count_;
}

bool Localizer::map_pose_horizon(TimestampNs& out) const noexcept {
  if (lagged_.empty()) {
    if (!filter_.started()) {
      return false;
    }
    out = filter_.last_stamp_ns();
    return true;
  }
  if (map_count_ == 0) {
    return false;
  }
  out = map_poses_[(map_first_ + map_count_ - 1) % map_poses_.size()].stamp_ns;
  return true;
}

bool Localizer::map_pose_at(TimestampNs stamp_ns, Pose3& out, Pose2* odometry) const noexcept {
  if (map_count_ == 0) {
    return false;
  }
  const auto at = [this](std::size_t i) -> const Pose3& {
    return map_poses_[(map_first_ + i) % map_poses_.size()];
  };
  if (stamp_ns < at(0).stamp_ns || stamp_ns > at(map_count_ - 1).stamp_ns) {
    return false;
  }
  // The last pose at or before the stamp, and the next one.
  std::size_t low = 0;
  std::size_t high = map_count_;
  while (high - low > 1) {
    const std::size_t mid = (low + high) / 2;
    if (at(mid).stamp_ns <= stamp_ns) {
      low = mid;
    } else {
      high = mid;
    }
  }
  const Pose3& a = at(low);
  if (low + 1 == map_count_ || a.stamp_ns == stamp_ns) {
    out = a;
    out.stamp_ns = stamp_ns;
    if (odometry != nullptr) {
      *odometry = odometry_poses_[(map_first_ + low) % map_poses_.size()];
      odometry->stamp_ns = stamp_ns;
    }
    return true;
  }
  const Pose3& b = at(low + 1);
  const double f =
      static_cast<double>(stamp_ns - a.stamp_ns) / static_cast<double>(b.stamp_ns - a.stamp_ns);
  out.stamp_ns = stamp_ns;
  out.x_m = a.x_m + f * (b.x_m - a.x_m);
  out.y_m = a.y_m + f * (b.y_m - a.y_m);
  out.z_m = a.z_m + f * (b.z_m - a.z_m);
  out.roll_rad = a.roll_rad + f * (b.roll_rad - a.roll_rad);
  out.pitch_rad = a.pitch_rad + f * (b.pitch_rad - a.pitch_rad);
  out.yaw_rad = wrap_angle(a.yaw_rad + f * wrap_angle(b.yaw_rad - a.yaw_rad));
  if (odometry != nullptr) {
    const Pose2& oa = odometry_poses_[(map_first_ + low) % map_poses_.size()];
    const Pose2& ob = odometry_poses_[(map_first_ + low + 1) % map_poses_.size()];
    odometry->stamp_ns = stamp_ns;
    odometry->x_m = oa.x_m + f * (ob.x_m - oa.x_m);
    odometry->y_m = oa.y_m + f * (ob.y_m - oa.y_m);
    odometry->yaw_rad = wrap_angle(oa.yaw_rad + f * wrap_angle(ob.yaw_rad - oa.yaw_rad));
  }
  return true;
}

void Localizer::record_if_stepped() noexcept {
  // The filter keeps a history step now and then (and one at a start); each gets the
  // attitude and height of its time, which the filter does not estimate.
  const std::uint64_t steps = filter_.counters().history_steps;
  if (steps == recorded_steps_) {
    return;
  }
  recorded_steps_ = steps;
  const Attitude attitude{filter_.newest_step_ns(), static_cast<float>(height_m_),
                          static_cast<float>(roll_rad_), static_cast<float>(pitch_rad_)};
  if (attitude_count_ == attitudes_.size()) {
    attitude_first_ = (attitude_first_ + 1) % attitudes_.size();
    --attitude_count_;
  }
  attitudes_[(attitude_first_ + attitude_count_) % attitudes_.size()] = attitude;
  ++attitude_count_;
}

Localizer::Attitude Localizer::attitude_at(TimestampNs stamp_ns) const noexcept {
  // The ring is in time order: the last entry at or before the stamp (or the first).
  if (attitude_count_ == 0) {
    return Attitude{stamp_ns, static_cast<float>(height_m_), static_cast<float>(roll_rad_),
                    static_cast<float>(pitch_rad_)};
  }
  std::size_t low = 0;
  std::size_t high = attitude_count_;
  while (high - low > 1) {
    const std::size_t mid = (low + high) / 2;
    if (attitudes_[(attitude_first_ + mid) % attitudes_.size()].stamp_ns <= stamp_ns) {
      low = mid;
    } else {
      high = mid;
    }
  }
  return attitudes_[(attitude_first_ + low) % attitudes_.size()];
}

Pose3 Localizer::completed(const Pose2& pose) const noexcept {
  const Attitude attitude = attitude_at(pose.stamp_ns);
  return Pose3{pose.stamp_ns,
               pose.x_m,
               pose.y_m,
               static_cast<double>(attitude.z_m),
               static_cast<double>(attitude.roll_rad),
               static_cast<double>(attitude.pitch_rad),
               pose.yaw_rad};
}

std::size_t Localizer::drain_final(std::span<Pose3> out) noexcept {
  const std::size_t n = filter_.drain_final(scratch_.first(std::min(out.size(), scratch_.size())));
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = completed(scratch_[i]);
  }
  return n;
}

std::size_t Localizer::smoothed_window(std::span<Pose3> out) const noexcept {
  const std::size_t n =
      filter_.smoothed_window(scratch_.first(std::min(out.size(), scratch_.size())));
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = completed(scratch_[i]);
  }
  return n;
}

bool Localizer::pose_at(TimestampNs stamp_ns, Pose3& out) const noexcept {
  Pose2 pose;
  if (!filter_.pose_at(stamp_ns, pose)) {
    return false;
  }
  out = completed(pose);
  return true;
}

}  // namespace blockmap::localize
