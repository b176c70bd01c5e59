#include "blockmap/pipeline/scan_planes.hpp"

#include <algorithm>
#include <cmath>

#include "blockmap/core/angles.hpp"

namespace blockmap::pipeline {

void ScanPlanes::init(double angle_deg, double distance_m, double spacing_m) noexcept {
  cos_angle_ = std::cos(radians_from_degrees(angle_deg));
  sin_angle_ = std::sin(radians_from_degrees(angle_deg));
  distance_m_ = distance_m;
  spacing_m_ = spacing_m;
}

void ScanPlanes::record(std::size_t laser, const map::ScanProjector& projector,
                        const localize::Pose3& pose) noexcept {
  LaserPath& path = paths_[laser];
  Eigen::Vector3d origin_m;
  projector.scan_plane(pose, origin_m, path.normal);
  const Eigen::Vector3d moved_m = origin_m - path.last_origin_m;
  if (moved_m.norm() < spacing_m_) {
    return;
  }
  path.last_origin_m = origin_m;
  // Only a laser moving within its own scan plane lays a sheet (a level laser, or a vertical
  // one looking along the way); one sweeping across the way paints a new slice each scan.
  if (std::abs(path.normal.dot(moved_m.normalized())) > sin_angle_) {
    return;
  }
  path.origins_m[path.next] = origin_m;
  path.next = (path.next + 1) % path.origins_m.size();
  path.count = std::min(path.count + 1, path.origins_m.size());
}

std::span<const planes::PlaneExclusion> ScanPlanes::exclusions(std::size_t laser_count) noexcept {
  std::size_t count = 0;
  for (std::size_t laser = 0; laser < laser_count; ++laser) {
    const LaserPath& path = paths_[laser];
    if (path.count > 0) {
      exclusions_[count++] = {std::span(path.origins_m).first(path.count), path.normal, cos_angle_,
                              distance_m_};
    }
  }
  return std::span(exclusions_).first(count);
}

}  // namespace blockmap::pipeline
