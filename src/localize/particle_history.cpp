// ParticleFilter's fixed-lag smoothing: the particles' poses of the last window kept by age,
// each particle's lineage traced back through the resamplings, and the smoothed path read
// from the surviving lineages, finalized as it leaves the window.
#include <algorithm>
#include <cmath>

#include "blockmap/core/angles.hpp"
#include "blockmap/localize/particle_filter.hpp"

namespace blockmap::localize {

std::size_t ParticleFilter::slot_of_age(std::size_t age) const noexcept {
  const std::size_t steps = config_.history_steps;
  return (history_newest_ + steps - age) % steps;
}

void ParticleFilter::push_history(TimestampNs stamp_ns) noexcept {
  const std::size_t steps = config_.history_steps;
  if (history_size_ == steps) {
    finalize_oldest();  // its slot is the one written next
  }
  const std::size_t slot = history_size_ == 0 ? 0 : (history_newest_ + 1) % steps;
  HistoryEntry* entries = history_.data() + slot * count_;
  for (std::size_t i = 0; i < count_; ++i) {
    entries[i] = HistoryEntry{static_cast<float>(x_m_[i]), static_cast<float>(y_m_[i]),
                              static_cast<float>(yaw_rad_[i]), ancestor_[i]};
    // The series rotations drift by ~1e-12 a step: start again from the yaw now and then.
    cos_yaw_[i] = std::cos(yaw_rad_[i]);
    sin_yaw_[i] = std::sin(yaw_rad_[i]);
    ancestor_[i] = static_cast<std::uint32_t>(i);
  }
  history_stamps_[slot] = stamp_ns;
  // Without a resampling since the last step every parent is the particle itself: tracing
  // back across this step changes nothing (a GPS outage costs no tracing at all).
  history_identity_[slot] = resampled_since_push_ ? 0 : 1;
  resampled_since_push_ = false;
  history_newest_ = slot;
  history_size_ = std::min(history_size_ + 1, steps);
  next_history_ns_ = stamp_ns + ns_from_seconds(config_.history_interval_s);
  ++counters_.history_steps;
}

void ParticleFilter::start_lineages() const noexcept {
  // Each current particle's entry at the newest step, with its weight now; particles that
  // share that entry are one lineage (their weights add).
  next_lineage_generation();
  for (std::size_t i = 0; i < count_; ++i) {
    add_to_lineage(ancestor_[i], weight_[i]);
  }
}

void ParticleFilter::next_lineage_generation() const noexcept {
  lineage_count_ = 0;
  if (++lineage_generation_ == 0) {  // wrapped: old marks would look current
    std::fill(lineage_seen_.begin(), lineage_seen_.end(), 0U);
    lineage_generation_ = 1;
  }
}

void ParticleFilter::add_to_lineage(std::uint32_t index, double weight) const noexcept {
  if (lineage_seen_[index] != lineage_generation_) {
    lineage_seen_[index] = lineage_generation_;
    lineage_slot_[index] = static_cast<std::uint32_t>(lineage_count_);
    trace_[lineage_count_] = index;
    trace_weight_[lineage_count_] = 0.0;
    ++lineage_count_;
  }
  trace_weight_[lineage_slot_[index]] += weight;
}

void ParticleFilter::step_lineages_back(std::size_t age) const noexcept {
  // From the entries at `age` to their parents one step older. Lineages merge as they go
  // back (resampling copied their ancestors), so after a few steps there are only a few.
  const std::size_t slot = slot_of_age(age);
  if (history_identity_[slot] != 0) {
    return;
  }
  const HistoryEntry* entries = history_.data() + slot * count_;
  const std::size_t count = lineage_count_;
  // The current list moves to the back half of the scratch while the new one is built.
  for (std::size_t k = 0; k < count; ++k) {
    chosen_[k] = trace_[k];
    scratch_[k] = trace_weight_[k];
  }
  next_lineage_generation();
  for (std::size_t k = 0; k < count; ++k) {
    add_to_lineage(entries[chosen_[k]].parent, scratch_[k]);
  }
}

Pose2 ParticleFilter::lineage_pose(std::size_t age) const noexcept {
  const std::size_t slot = slot_of_age(age);
  const HistoryEntry* entries = history_.data() + slot * count_;
  Pose2 pose;
  pose.stamp_ns = history_stamps_[slot];
  double sin_sum = 0.0;
  double cos_sum = 0.0;
  for (std::size_t k = 0; k < lineage_count_; ++k) {
    const HistoryEntry& e = entries[trace_[k]];
    const double w = trace_weight_[k];
    pose.x_m += w * static_cast<double>(e.x_m);
    pose.y_m += w * static_cast<double>(e.y_m);
    sin_sum += w * std::sin(static_cast<double>(e.yaw_rad));
    cos_sum += w * std::cos(static_cast<double>(e.yaw_rad));
  }
  pose.yaw_rad = std::atan2(sin_sum, cos_sum);
  return pose;
}

Pose2 ParticleFilter::smoothed_at(std::size_t age) const noexcept {
  // Each current particle's ancestor `age` steps back, weighed by the particle's weight now:
  // the particles that survived later fixes vote for where the robot was.
  start_lineages();
  for (std::size_t back = 0; back < age; ++back) {
    step_lineages_back(back);
  }
  return lineage_pose(age);
}

void ParticleFilter::finalize_oldest() noexcept {
  const Pose2 pose = smoothed_at(history_size_ - 1);
  if (final_count_ == final_.size()) {
    ++counters_.final_poses_dropped;  // the consumer is not draining: keep the newest
    final_first_ = (final_first_ + 1) % final_.size();
    --final_count_;
  }
  final_[(final_first_ + final_count_) % final_.size()] = pose;
  ++final_count_;
}

std::size_t ParticleFilter::drain_final(std::span<Pose2> out) noexcept {
  const std::size_t n = std::min(out.size(), final_count_);
  for (std::size_t k = 0; k < n; ++k) {
    out[k] = final_[final_first_];
    final_first_ = (final_first_ + 1) % final_.size();
  }
  final_count_ -= n;
  return n;
}

std::size_t ParticleFilter::smoothed_window(std::span<Pose2> out) const noexcept {
  const std::size_t n = std::min(out.size(), history_size_);
  // One pass back from the newest step; out is oldest first.
  start_lineages();
  for (std::size_t age = 0; age < n; ++age) {
    if (age > 0) {
      step_lineages_back(age - 1);
    }
    out[n - 1 - age] = lineage_pose(age);
  }
  return n;
}

Pose2 ParticleFilter::interpolate(const Pose2& earlier, const Pose2& later,
                                  TimestampNs stamp_ns) noexcept {
  const double span_s = seconds_from_ns(later.stamp_ns - earlier.stamp_ns);
  const double f = span_s > 0.0 ? seconds_from_ns(stamp_ns - earlier.stamp_ns) / span_s : 0.0;
  Pose2 out;
  out.stamp_ns = stamp_ns;
  out.x_m = earlier.x_m + f * (later.x_m - earlier.x_m);
  out.y_m = earlier.y_m + f * (later.y_m - earlier.y_m);
  out.yaw_rad = wrap_angle(earlier.yaw_rad + f * wrap_angle(later.yaw_rad - earlier.yaw_rad));
  return out;
}

bool ParticleFilter::pose_at(TimestampNs stamp_ns, Pose2& out) const noexcept {
  if (!started_ || history_size_ == 0) {
    return false;
  }
  const std::size_t oldest_slot = slot_of_age(history_size_ - 1);
  if (stamp_ns < history_stamps_[oldest_slot] || stamp_ns > last_stamp_ns_) {
    return false;
  }
  // On the smoothed path: the current particles' weighted ancestry at the history steps, as
  // smoothed_window() gives it, and their weighted mean after the newest step. One particle's
  // path would carry that particle's own noise (degrees of heading with thousands of them).
  // After the newest step (where a mapper asks, twice per scan), the two ends are kept until
  // the filter changes: each costs a pass over the particles.
  if (stamp_ns >= history_stamps_[history_newest_]) {
    if (newest_span_version_ != version_) {
      newest_span_later_ = estimate();
      start_lineages();
      newest_span_earlier_ = lineage_pose(0);
      newest_span_version_ = version_;
    }
    out = interpolate(newest_span_earlier_, newest_span_later_, stamp_ns);
    return true;
  }
  // Back from the newest step to the first one at or before the stamp; only the two steps
  // around it are averaged (each costs a pass over the lineages and a sine and cosine each).
  Pose2 later = estimate();
  start_lineages();
  for (std::size_t age = 0; age < history_size_; ++age) {
    const bool bracketed = history_stamps_[slot_of_age(age)] <= stamp_ns;
    if (age > 0) {
      if (bracketed) {
        later = lineage_pose(age - 1);
      }
      step_lineages_back(age - 1);
    }
    if (bracketed) {
      out = interpolate(lineage_pose(age), later, stamp_ns);
      return true;
    }
  }
  return false;
}

}  // namespace blockmap::localize
