// Plane lists made by hand for the building tests: vertical walls between two points of the
// ground plan, as the plane detector reports them (a rectangle polygon on the plane).
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <Eigen/Core>

#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::testing {

inline msg::PlanePatch vertical_plane(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m,
                                      double z0_m, double z1_m, std::uint32_t id,
                                      msg::PlaneKind kind = msg::PlaneKind::kWall) {
  msg::PlanePatch plane;
  plane.id = id;
  plane.kind = kind;
  const Eigen::Vector2d along = (to_m - from_m).normalized();
  plane.normal = Eigen::Vector3d(along.y(), -along.x(), 0.0);
  const Eigen::Vector2d middle = 0.5 * (from_m + to_m);
  plane.centroid_m = Eigen::Vector3d(middle.x(), middle.y(), 0.5 * (z0_m + z1_m));
  plane.d_m = plane.normal.dot(plane.centroid_m);
  plane.support = 1000.0 * (to_m - from_m).norm();
  plane.polygon_m[0] = Eigen::Vector3d(from_m.x(), from_m.y(), z0_m);
  plane.polygon_m[1] = Eigen::Vector3d(to_m.x(), to_m.y(), z0_m);
  plane.polygon_m[2] = Eigen::Vector3d(to_m.x(), to_m.y(), z1_m);
  plane.polygon_m[3] = Eigen::Vector3d(from_m.x(), from_m.y(), z1_m);
  plane.polygon_size = 4;
  return plane;
}

// A flat roof over the axis-aligned box [lo, hi] at height z_m.
inline msg::PlanePatch flat_roof(const Eigen::Vector2d& lo_m, const Eigen::Vector2d& hi_m,
                                 double z_m, std::uint32_t id) {
  msg::PlanePatch plane;
  plane.id = id;
  plane.kind = msg::PlaneKind::kRoof;
  plane.normal = Eigen::Vector3d::UnitZ();
  plane.d_m = z_m;
  const Eigen::Vector2d middle = 0.5 * (lo_m + hi_m);
  plane.centroid_m = Eigen::Vector3d(middle.x(), middle.y(), z_m);
  plane.support = (hi_m - lo_m).prod() * 100.0;
  plane.polygon_m[0] = Eigen::Vector3d(lo_m.x(), lo_m.y(), z_m);
  plane.polygon_m[1] = Eigen::Vector3d(hi_m.x(), lo_m.y(), z_m);
  plane.polygon_m[2] = Eigen::Vector3d(hi_m.x(), hi_m.y(), z_m);
  plane.polygon_m[3] = Eigen::Vector3d(lo_m.x(), hi_m.y(), z_m);
  plane.polygon_size = 4;
  return plane;
}

// Walls along a closed ground plan (counter-clockwise corners), each `inset_m` short of both
// of its corners (a detector's extents stop short where the corner's samples are shared).
inline std::vector<msg::PlanePatch> walls_around(const std::vector<Eigen::Vector2d>& corners_m,
                                                 double height_m, double inset_m = 0.2,
                                                 std::uint32_t first_id = 1) {
  std::vector<msg::PlanePatch> planes;
  for (std::size_t k = 0; k < corners_m.size(); ++k) {
    const Eigen::Vector2d& a = corners_m[k];
    const Eigen::Vector2d& b = corners_m[(k + 1) % corners_m.size()];
    const Eigen::Vector2d along = (b - a).normalized();
    planes.push_back(vertical_plane(a + inset_m * along, b - inset_m * along, 0.0, height_m,
                                    first_id + static_cast<std::uint32_t>(k)));
  }
  return planes;
}

// Ground plans as the simulated worlds build them (counter-clockwise from the front's left
// end): a rect 20 x 12 m, an L 20 x 14 m without an 8 x 6 m corner, a T of a 24 x 6 m bar and
// an 8 x 10 m stem.
inline const std::vector<Eigen::Vector2d> kRectPlan{{-10, -6}, {10, -6}, {10, 6}, {-10, 6}};
inline const std::vector<Eigen::Vector2d> kLPlan{{-10, -7}, {10, -7}, {10, 1},
                                                 {2, 1},    {2, 7},   {-10, 7}};
inline const std::vector<Eigen::Vector2d> kTPlan{{-4, -8}, {4, -8},  {4, 2},   {12, 2},
                                                 {12, 8},  {-12, 8}, {-12, 2}, {-4, 2}};

// The ground plan turned by yaw_deg about the origin and moved by offset_m.
inline std::vector<Eigen::Vector2d> placed(std::vector<Eigen::Vector2d> corners, double yaw_deg,
                                           const Eigen::Vector2d& offset_m) {
  const double yaw = yaw_deg * std::numbers::pi / 180.0;
  const Eigen::Matrix2d rotation{{std::cos(yaw), -std::sin(yaw)}, {std::sin(yaw), std::cos(yaw)}};
  for (Eigen::Vector2d& corner : corners) {
    corner = rotation * corner + offset_m;
  }
  return corners;
}

}  // namespace blockmap::testing
