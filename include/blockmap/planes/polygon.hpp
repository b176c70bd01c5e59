// Small fixed-size geometry for plane extents: a basis on a plane, convex hulls in it, their
// simplification and the gap between two of them. No allocation: callers pass the buffers.
#pragma once

#include <algorithm>
#include <cstddef>
#include <span>
#include <utility>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace blockmap::planes {

// Two unit vectors spanning the plane with this normal. For walls the first is horizontal
// and the second points up the wall, so a wall's extent reads as length and height.
[[nodiscard]] std::pair<Eigen::Vector3d, Eigen::Vector3d> plane_basis(
    const Eigen::Vector3d& normal_unit) noexcept;

// The convex hull of `points` (reordered in place), counter-clockwise, into `hull` (size at
// least points.size() + 1). Returns the hull's vertex count.
std::size_t convex_hull(std::span<Eigen::Vector2d> points,
                        std::span<Eigen::Vector2d> hull) noexcept;

// Drops the vertices that add least area until at most max_vertices remain; returns the count.
std::size_t simplify_polygon(std::span<Eigen::Vector2d> polygon, std::size_t size,
                             std::size_t max_vertices) noexcept;

// The smallest distance between two convex polygons (counter-clockwise), 0 when they overlap.
[[nodiscard]] double convex_polygon_gap(std::span<const Eigen::Vector2d> a,
                                        std::span<const Eigen::Vector2d> b) noexcept;

[[nodiscard]] double polygon_area(std::span<const Eigen::Vector2d> polygon) noexcept;

// The distance from p to the segment a-b. Inline: building fitting calls it in its innermost
// loop, from another translation unit.
[[nodiscard]] inline double point_segment_distance(const Eigen::Vector2d& p,
                                                   const Eigen::Vector2d& a,
                                                   const Eigen::Vector2d& b) noexcept {
  const Eigen::Vector2d ab = b - a;
  const double length_sq = ab.squaredNorm();
  const double t = length_sq > 0.0 ? std::clamp((p - a).dot(ab) / length_sq, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

// Whether p lies inside a simple polygon, convex or not (even-odd rule).
[[nodiscard]] bool inside_polygon(const Eigen::Vector2d& p,
                                  std::span<const Eigen::Vector2d> polygon) noexcept;

}  // namespace blockmap::planes
