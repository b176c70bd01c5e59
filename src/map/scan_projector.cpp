#include "blockmap/map/scan_projector.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace blockmap::map {
namespace {

Eigen::Vector3d position_of(const localize::Pose3& pose) noexcept {
  return {pose.x_m, pose.y_m, pose.z_m};
}

}  // namespace

Eigen::Matrix3d mount_rotation(const SensorMount& mount) noexcept {
  return localize::attitude_rotation(mount.roll_rad, mount.pitch_rad, mount.yaw_rad);
}

Eigen::Matrix3d robot_rotation(const localize::Pose3& pose) noexcept {
  return localize::attitude_rotation(pose.roll_rad, pose.pitch_rad, pose.yaw_rad);
}

ScanProjector::ScanProjector(const SensorMount& mount, const ScanProjectorConfig& config) noexcept
    : mount_(mount), config_(config), mount_rotation_(mount_rotation(mount)) {}

TimestampNs ScanProjector::beam_stamp_ns(const msg::LaserScan& scan, std::uint32_t beam) noexcept {
  return scan.header.stamp_ns + ns_from_seconds(static_cast<double>(beam) * scan.time_increment_s);
}

TimestampNs ScanProjector::last_beam_stamp_ns(const msg::LaserScan& scan) noexcept {
  return beam_stamp_ns(scan, scan.beam_count > 0 ? scan.beam_count - 1U : 0U);
}

void ScanProjector::scan_plane(const localize::Pose3& pose, Eigen::Vector3d& origin_m,
                               Eigen::Vector3d& normal) const noexcept {
  const Eigen::Matrix3d rotation = robot_rotation(pose);
  origin_m = position_of(pose) + rotation * mount_.position_m;
  normal = rotation * mount_rotation_.col(2);  // beams sweep the laser's x-y plane
}

void ScanProjector::update_beam_directions(const msg::LaserScan& scan) noexcept {
  if (scan.beam_count == table_beams_ && scan.start_angle_rad == table_start_rad_ &&
      scan.angle_increment_rad == table_increment_rad_) {
    return;
  }
  for (std::uint16_t i = 0; i < scan.beam_count; ++i) {
    const double angle = scan.start_angle_rad + static_cast<double>(i) * scan.angle_increment_rad;
    beam_directions_[i] = mount_rotation_ * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.0);
  }
  table_beams_ = scan.beam_count;
  table_start_rad_ = scan.start_angle_rad;
  table_increment_rad_ = scan.angle_increment_rad;
}

std::size_t ScanProjector::project(const msg::LaserScan& scan, const localize::Pose3& first,
                                   const localize::Pose3& last,
                                   std::span<Eigen::Vector3f> out) noexcept {
  ++counters_.scans;
  update_beam_directions(scan);
  // The laser's origin and axes in the local frame at the first and the last beam; a beam in
  // between takes the straight line between them (the simulator does the same).
  const Eigen::Matrix3d rotation_first = robot_rotation(first);
  const Eigen::Matrix3d rotation_last = robot_rotation(last);
  const Eigen::Vector3d origin_first = position_of(first) + rotation_first * mount_.position_m;
  const Eigen::Vector3d origin_last = position_of(last) + rotation_last * mount_.position_m;
  const auto span_ns = static_cast<double>(last.stamp_ns - first.stamp_ns);
  std::size_t count = 0;
  for (std::uint16_t i = 0; i < scan.beam_count; ++i) {
    switch (scan.status[i]) {
      case msg::BeamStatus::kValid:
        break;
      case msg::BeamStatus::kNoReturn:
        ++counters_.no_return;
        continue;
      case msg::BeamStatus::kDazzled:
      case msg::BeamStatus::kDeviceError:
      case msg::BeamStatus::kTooClose:
        ++counters_.flagged;
        continue;
    }
    const auto range_m = static_cast<double>(scan.ranges_m[i]);
    if (!std::isfinite(range_m)) {
      ++counters_.non_finite;
      continue;
    }
    if (range_m < config_.min_range_m) {
      ++counters_.below_min_range;
      continue;
    }
    if (range_m > config_.max_range_m) {
      ++counters_.beyond_max_range;
      continue;
    }
    if (count == out.size()) {
      ++counters_.output_full;
      continue;
    }
    const double f =
        span_ns > 0.0
            ? std::clamp(static_cast<double>(beam_stamp_ns(scan, i) - first.stamp_ns) / span_ns,
                         0.0, 1.0)
            : 0.0;
    const Eigen::Vector3d& beam = beam_directions_[i];
    const Eigen::Vector3d origin = origin_first + f * (origin_last - origin_first);
    const Eigen::Vector3d direction =
        (rotation_first * beam + f * (rotation_last - rotation_first) * beam).normalized();
    out[count++] = (origin + range_m * direction).cast<float>();
  }
  counters_.points += count;
  return count;
}

std::size_t ScanProjector::drop_far_ground(const localize::Pose3& pose,
                                           std::span<Eigen::Vector3f> points_m) noexcept {
  if (!(config_.far_ground_range_m > 0.0)) {
    return points_m.size();
  }
  // The ground under the robot lies the axle's height below its origin along the vertical (the
  // RMP pitches about its axle). A scan lasts 13 ms: the laser's origin at its first beam
  // stands for all of them, a centimetre off at most.
  const auto ground_z_m = static_cast<float>(pose.z_m - config_.axle_height_m);
  const auto band_m = static_cast<float>(config_.ground_band_m);
  const Eigen::Vector2f laser_xy_m =
      (position_of(pose) + robot_rotation(pose) * mount_.position_m).head<2>().cast<float>();
  const auto far_sq_m2 =
      static_cast<float>(config_.far_ground_range_m * config_.far_ground_range_m);
  std::size_t kept = 0;
  for (const Eigen::Vector3f& point_m : points_m) {
    const bool far_ground = point_m.z() - ground_z_m < band_m &&
                            (point_m.head<2>() - laser_xy_m).squaredNorm() > far_sq_m2;
    if (far_ground) {
      ++counters_.far_ground;
    } else {
      points_m[kept++] = point_m;
    }
  }
  return kept;
}

}  // namespace blockmap::map
