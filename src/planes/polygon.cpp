#include "blockmap/planes/polygon.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace blockmap::planes {
namespace {

double cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

bool inside_convex(const Eigen::Vector2d& p, std::span<const Eigen::Vector2d> polygon) {
  if (polygon.size() < 3) {
    return false;
  }
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    if (cross(polygon[i], polygon[(i + 1) % polygon.size()], p) < 0.0) {
      return false;
    }
  }
  return true;
}

}  // namespace

std::pair<Eigen::Vector3d, Eigen::Vector3d> plane_basis(
    const Eigen::Vector3d& normal_unit) noexcept {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d u = up.cross(normal_unit);
  if (u.norm() < 0.5) {
    u = normal_unit.cross(Eigen::Vector3d::UnitX()).cross(normal_unit);  // near-horizontal plane: x
  }
  u.normalize();
  return {u, normal_unit.cross(u).normalized()};
}

namespace {

std::size_t drop_points_inside_extremes(std::span<Eigen::Vector2d> points) noexcept {
  // Akl and Toussaint: the points furthest left, down, right and up span a quadrilateral
  // inside the hull; a point well inside it is no hull vertex (a merged wall's section
  // corners are mostly such points). The margin keeps every point near an edge, so that the
  // chain decides those as it would with all points.
  std::array<std::size_t, 4> extreme{};  // left, bottom, right, top: counter-clockwise
  for (std::size_t i = 1; i < points.size(); ++i) {
    const Eigen::Vector2d& p = points[i];
    extreme[0] = p.x() < points[extreme[0]].x() ? i : extreme[0];
    extreme[1] = p.y() < points[extreme[1]].y() ? i : extreme[1];
    extreme[2] = p.x() > points[extreme[2]].x() ? i : extreme[2];
    extreme[3] = p.y() > points[extreme[3]].y() ? i : extreme[3];
  }
  std::array<Eigen::Vector2d, 4> corner;
  for (std::size_t e = 0; e < corner.size(); ++e) {
    corner[e] = points[extreme[e]];
  }
  const double extent = (corner[2].x() - corner[0].x()) + (corner[3].y() - corner[1].y());
  const double margin = 1e-9 * extent * extent;
  std::size_t kept = 0;
  for (const Eigen::Vector2d& p : points) {
    bool well_inside = true;
    for (std::size_t e = 0; e < corner.size() && well_inside; ++e) {
      well_inside = cross(corner[e], corner[(e + 1) % corner.size()], p) > margin;
    }
    if (!well_inside) {
      points[kept++] = p;
    }
  }
  return kept;
}

}  // namespace

std::size_t convex_hull(std::span<Eigen::Vector2d> points,
                        std::span<Eigen::Vector2d> hull) noexcept {
  constexpr std::size_t kFewPoints = 16;  // below this, sorting them all is as quick
  if (points.size() > kFewPoints) {
    points = points.first(drop_points_inside_extremes(points));
  }
  const std::size_t n = points.size();
  if (n < 3) {
    std::copy(points.begin(), points.end(), hull.begin());
    return n;
  }
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y();
  });
  // Andrew's monotone chain: lower hull left to right, upper hull right to left.
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0.0) {
      --k;
    }
    hull[k++] = points[i];
  }
  const std::size_t lower = k + 1;
  for (std::size_t i = n - 1; i-- > 0;) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i]) <= 0.0) {
      --k;
    }
    hull[k++] = points[i];
  }
  return k - 1;  // the last point repeats the first
}

std::size_t simplify_polygon(std::span<Eigen::Vector2d> polygon, std::size_t size,
                             std::size_t max_vertices) noexcept {
  while (size > max_vertices && size > 3) {
    std::size_t weakest = 0;
    double weakest_area = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < size; ++i) {
      const double area =
          std::abs(cross(polygon[(i + size - 1) % size], polygon[i], polygon[(i + 1) % size]));
      if (area < weakest_area) {
        weakest_area = area;
        weakest = i;
      }
    }
    std::copy(polygon.begin() + static_cast<std::ptrdiff_t>(weakest) + 1,
              polygon.begin() + static_cast<std::ptrdiff_t>(size),
              polygon.begin() + static_cast<std::ptrdiff_t>(weakest));
    --size;
  }
  return size;
}

double convex_polygon_gap(std::span<const Eigen::Vector2d> a,
                          std::span<const Eigen::Vector2d> b) noexcept {
  if (a.empty() || b.empty()) {
    return std::numeric_limits<double>::infinity();
  }
  if (inside_convex(a[0], b) || inside_convex(b[0], a)) {
    return 0.0;
  }
  double gap = std::numeric_limits<double>::infinity();
  const auto edges_to_points = [&gap](std::span<const Eigen::Vector2d> edges,
                                      std::span<const Eigen::Vector2d> points) {
    for (std::size_t i = 0; i < edges.size(); ++i) {
      const Eigen::Vector2d& p0 = edges[i];
      const Eigen::Vector2d& p1 = edges[(i + 1) % edges.size()];
      for (const Eigen::Vector2d& p : points) {
        gap = std::min(gap, point_segment_distance(p, p0, p1));
      }
    }
  };
  edges_to_points(a, b);
  edges_to_points(b, a);
  // Crossing edges with no vertex inside the other polygon: the gap is 0.
  for (std::size_t i = 0; i < a.size() && gap > 0.0; ++i) {
    const Eigen::Vector2d& a0 = a[i];
    const Eigen::Vector2d& a1 = a[(i + 1) % a.size()];
    for (std::size_t j = 0; j < b.size(); ++j) {
      const Eigen::Vector2d& b0 = b[j];
      const Eigen::Vector2d& b1 = b[(j + 1) % b.size()];
      if (cross(a0, a1, b0) * cross(a0, a1, b1) < 0.0 &&
          cross(b0, b1, a0) * cross(b0, b1, a1) < 0.0) {
        return 0.0;
      }
    }
  }
  return gap;
}

double polygon_area(std::span<const Eigen::Vector2d> polygon) noexcept {
  double twice = 0.0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector2d& p = polygon[i];
    const Eigen::Vector2d& q = polygon[(i + 1) % polygon.size()];
    twice += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * twice;
}

bool inside_polygon(const Eigen::Vector2d& p, std::span<const Eigen::Vector2d> polygon) noexcept {
  bool inside = false;
  for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

}  // namespace blockmap::planes
