#include "blockmap/pipeline/scan_poses.hpp"

#include <algorithm>

#include "blockmap/core/angles.hpp"

namespace blockmap::pipeline {
namespace {

localize::Pose3 interpolated(const localize::Pose3& a, const localize::Pose3& b,
                             TimestampNs stamp_ns) noexcept {
  const double span_s = seconds_from_ns(b.stamp_ns - a.stamp_ns);
  const double f = span_s > 0.0 ? seconds_from_ns(stamp_ns - a.stamp_ns) / span_s : 0.0;
  const auto mix = [f](double x, double y) { return x + f * (y - x); };
  localize::Pose3 out;
  out.stamp_ns = stamp_ns;
  out.x_m = mix(a.x_m, b.x_m);
  out.y_m = mix(a.y_m, b.y_m);
  out.z_m = mix(a.z_m, b.z_m);
  out.roll_rad = mix(a.roll_rad, b.roll_rad);
  out.pitch_rad = mix(a.pitch_rad, b.pitch_rad);
  out.yaw_rad = wrap_angle(a.yaw_rad + f * wrap_angle(b.yaw_rad - a.yaw_rad));
  return out;
}

}  // namespace

void ScanPoses::init(Arena& arena, PoseSource source, const localize::LocalizerConfig& localizer,
                     std::size_t max_external_poses) {
  source_ = source;
  lag_s_ = localizer.map_pose_lag_s;
  localizer_.init(arena, localizer);
  if (source == PoseSource::kExternal) {
    given_.init(arena, max_external_poses, "mapper.poses");
  }
}

std::size_t ScanPoses::arena_bytes(PoseSource source, const localize::LocalizerConfig& localizer,
                                   std::size_t max_external_poses) noexcept {
  return localize::Localizer::arena_bytes(localizer) +
         (source == PoseSource::kExternal ? max_external_poses : 0) * sizeof(localize::Pose3);
}

void ScanPoses::on_base(const msg::OdometrySample& odometry, const msg::ImuSample& imu) noexcept {
  last_in_ns_ = odometry.header.stamp_ns;
  any_in_ = true;
  last_base_ns_ = odometry.header.stamp_ns;
  any_base_ = true;
  localizer_.on_base(odometry, imu);
}

localize::GpsOutcome ScanPoses::on_fix(const localize::GpsObservation& fix, double up_m) noexcept {
  last_in_ns_ = fix.stamp_ns;
  any_in_ = true;
  return localizer_.on_fix(fix, up_m);
}

void ScanPoses::on_pose(const localize::Pose3& pose) noexcept {
  last_in_ns_ = pose.stamp_ns;
  any_in_ = true;
  if (source_ == PoseSource::kExternal) {
    given_.push_overwrite(pose);
    undrained_ = std::min(undrained_ + 1, given_.size());
  }
}

std::size_t ScanPoses::drain_given(std::span<localize::Pose3> out) noexcept {
  const std::size_t n = std::min(undrained_, out.size());
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = given_[given_.size() - undrained_ + i];
  }
  undrained_ -= n;
  return n;
}

bool ScanPoses::horizon(TimestampNs& out) const noexcept {
  if (source_ == PoseSource::kLocalizer) {
    return localizer_.map_pose_horizon(out);
  }
  if (given_.empty()) {
    return false;
  }
  out = given_.back().stamp_ns;
  return true;
}

bool ScanPoses::at(TimestampNs stamp_ns, localize::Pose3& out) const noexcept {
  if (source_ == PoseSource::kLocalizer) {
    return localizer_.map_pose_at(stamp_ns, out);
  }
  for (std::size_t k = 1; k < given_.size(); ++k) {
    const localize::Pose3& a = given_[k - 1];
    const localize::Pose3& b = given_[k];
    if (a.stamp_ns <= stamp_ns && stamp_ns <= b.stamp_ns) {
      out = interpolated(a, b, stamp_ns);
      return true;
    }
  }
  return false;
}

bool ScanPoses::first_pose_bound(TimestampNs& bound_ns) const noexcept {
  if (source_ == PoseSource::kExternal) {
    // The first given pose is no older than the next message released.
    bound_ns = last_in_ns_;
    return any_in_;
  }
  bound_ns = last_base_ns_ - ns_from_seconds(lag_s_);
  return any_base_;
}

}  // namespace blockmap::pipeline
