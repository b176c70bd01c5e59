// A plane of the map: the plane list's entry (docs: the plane list JSON).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include <Eigen/Core>

namespace blockmap::msg {

enum class PlaneKind : std::uint8_t { kWall, kRoof, kGround, kOther };

[[nodiscard]] constexpr std::string_view to_string(PlaneKind kind) noexcept {
  switch (kind) {
    case PlaneKind::kWall:
      return "wall";
    case PlaneKind::kRoof:
      return "roof";
    case PlaneKind::kGround:
      return "ground";
    case PlaneKind::kOther:
      return "other";
  }
  return "other";
}

inline constexpr std::size_t kMaxPolygonVertices = 32;

struct PlanePatch {
  std::uint32_t id = 0;
  PlaneKind kind = PlaneKind::kOther;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit; normal . x = d_m
  double d_m = 0.0;
  double support = 0.0;  // points behind the plane
  double rmse_m = 0.0;   // RMS distance of those points to the plane
  Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();
  // The observed extent: the convex hull of the plane's points, on the plane, in order.
  std::array<Eigen::Vector3d, kMaxPolygonVertices> polygon_m{};
  std::uint8_t polygon_size = 0;
};

// What happened to a plane of the mapper's list, as its stream reports it (a consumer applies
// the changes by id): new, updated while its region is still mapped, final (its region left
// the mapper's window; reported again only when the robot comes back to it or the rigid
// path's solve moves it), or removed (merged into another plane, or
// no longer seen in what the window holds: a consumer drops it; its id never comes back).
enum class PlaneChangeKind : std::uint8_t {
  kAdded = 1,
  kChanged = 2,
  kFinalized = 3,
  kRemoved = 4
};

struct PlaneChange {
  PlaneChangeKind change = PlaneChangeKind::kAdded;
  PlanePatch plane;
};

}  // namespace blockmap::msg
