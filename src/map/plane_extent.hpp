// A plane's extent, as the registry compares and joins planes by it.
#pragma once

#include <span>

#include <Eigen/Geometry>

#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::map {

[[nodiscard]] inline std::span<const Eigen::Vector3d> polygon_of(
    const msg::PlanePatch& plane) noexcept {
  return {plane.polygon_m.data(), plane.polygon_size};
}

[[nodiscard]] inline Eigen::AlignedBox3d box_of(std::span<const Eigen::Vector3d> polygon) noexcept {
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : polygon) {
    box.extend(p);
  }
  return box;
}

}  // namespace blockmap::map
