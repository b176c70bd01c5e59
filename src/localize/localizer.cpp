#include "blockmap/localize/localizer.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "blockmap/core/check.hpp"

namespace blockmap::localize {

std::string validate(const LocalizerConfig& config) {
  std::string problem = validate(config.filter);
  if (!problem.empty()) {
    return problem;
  }
  if (!(config.height_smoothing_s >= 0.0) || !(config.max_speed_mps > 0.0)) {
    return "height_smoothing_s must be >= 0 and max_speed_mps > 0";
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
}

std::size_t Localizer::arena_bytes(const LocalizerConfig& config) noexcept {
  constexpr std::size_t kAlignment = 64;
  return ParticleFilter::arena_bytes(config.filter) +
         (config.filter.history_steps + 1) * sizeof(Attitude) +
         config.filter.history_steps * sizeof(Pose2) + 2 * kAlignment;
}

std::size_t Localizer::memory_bytes() const noexcept {
  return filter_.memory_bytes() + attitudes_.size_bytes() + scratch_.size_bytes();
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
  filter_.predict(stamp_ns, distance_m, imu.yaw_rate_radps);
  record_if_stepped();
}

GpsOutcome Localizer::on_fix(const GpsObservation& fix, double up_m) noexcept {
  const GpsOutcome outcome = filter_.update(fix);
  if (outcome != GpsOutcome::kRejected) {
    // The robot frame's height: the antenna's less its mount, low-passed.
    const double height_m = up_m - config_.antenna_height_m;
    if (!have_height_) {
      height_m_ = height_m;
      have_height_ = true;
    } else {
      const double dt_s = std::max(0.0, seconds_from_ns(fix.stamp_ns - last_height_ns_));
      height_m_ += (height_m - height_m_) * dt_s / (config_.height_smoothing_s + dt_s);
    }
    last_height_ns_ = fix.stamp_ns;
  }
  record_if_stepped();
  return outcome;
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
