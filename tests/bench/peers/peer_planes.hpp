// What the peer benchmark needs from every plane detector it compares: the planes as the
// plane list's entries, so that one scorer (tests/support/plane_truth.hpp) judges them all.
// A peer labels points (plane index or -1); the planes are then built from the labels the
// same way for every peer: a least-squares fit, the convex hull of the points on the plane,
// and the label by orientation.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/point_moments.hpp"
#include "blockmap/planes/polygon.hpp"

namespace blockmap::bench {

// The same thresholds for every peer, in the units blockmap's defaults use.
struct PeerParameters {
  double distance_m = 0.10;            // a point within this of a plane is its inlier
  std::size_t min_plane_points = 200;  // the scored faces have at least 200 returns
  std::size_t max_planes = 400;
  double time_limit_s = 300.0;  // iterative peers stop here, and say so
  double label_tolerance_deg = 5.0;
};

struct PeerRun {
  std::string name;
  double seconds = 0.0;  // from points to planes, normals included where the peer needs them
  std::vector<msg::PlanePatch> planes;
  std::string note;  // how it was run, or why it stopped early
};

class Stopwatch {
 public:
  [[nodiscard]] double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// One plane from the points with `label`: fitted, bounded by its points' hull, labelled wall
// (vertical), roof or ground (horizontal; ground when it is the lowest) or other. A fit
// whose RMS distance exceeds the inlier distance is not a plane (a tree, a car) and is
// labelled other.
inline std::vector<msg::PlanePatch> planes_from_labels(std::span<const Eigen::Vector3f> points,
                                                       std::span<const std::int32_t> labels,
                                                       const PeerParameters& parameters) {
  std::int32_t count = 0;
  for (const std::int32_t label : labels) {
    count = std::max(count, label + 1);
  }
  std::vector<std::vector<std::uint32_t>> members(static_cast<std::size_t>(count));
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] >= 0) {
      members[static_cast<std::size_t>(labels[i])].push_back(static_cast<std::uint32_t>(i));
    }
  }
  const double vertical = std::sin(parameters.label_tolerance_deg * std::numbers::pi / 180.0);
  const double horizontal = std::cos(parameters.label_tolerance_deg * std::numbers::pi / 180.0);
  std::vector<msg::PlanePatch> planes;
  for (const std::vector<std::uint32_t>& indices : members) {
    if (indices.size() < 3) {
      continue;
    }
    planes::PointMoments moments;
    for (const std::uint32_t i : indices) {
      moments.add(points[i].cast<double>());
    }
    const planes::PlaneFit fit = planes::fit_plane(moments);
    if (!fit.valid) {
      continue;
    }
    msg::PlanePatch plane;
    plane.id = static_cast<std::uint32_t>(planes.size() + 1);
    plane.normal = fit.normal_unit;
    plane.d_m = fit.d_m;
    plane.support = static_cast<double>(indices.size());
    plane.rmse_m = fit.rmse_m;
    plane.centroid_m = fit.centroid_m;
    const auto [u, v] = planes::plane_basis(fit.normal_unit);
    std::vector<Eigen::Vector2d> on_plane;
    on_plane.reserve(indices.size());
    for (const std::uint32_t i : indices) {
      const Eigen::Vector3d p = points[i].cast<double>() - fit.centroid_m;
      on_plane.emplace_back(u.dot(p), v.dot(p));
    }
    std::vector<Eigen::Vector2d> hull(on_plane.size() + 1);
    std::size_t size = planes::convex_hull(on_plane, hull);
    size = planes::simplify_polygon(hull, size, msg::kMaxPolygonVertices);
    for (std::size_t k = 0; k < size; ++k) {
      plane.polygon_m[k] = fit.centroid_m + hull[k].x() * u + hull[k].y() * v;
    }
    plane.polygon_size = static_cast<std::uint8_t>(size);
    const double z = std::abs(fit.normal_unit.z());
    if (fit.rmse_m > parameters.distance_m) {
      plane.kind = msg::PlaneKind::kOther;
    } else if (z <= vertical) {
      plane.kind = msg::PlaneKind::kWall;
    } else if (z >= horizontal) {
      plane.kind = msg::PlaneKind::kRoof;  // the lowest large one becomes ground below
    }
    planes.push_back(plane);
  }
  // The ground: the horizontal plane with most points.
  msg::PlanePatch* ground = nullptr;
  for (msg::PlanePatch& plane : planes) {
    if (plane.kind == msg::PlaneKind::kRoof &&
        (ground == nullptr || plane.support > ground->support)) {
      ground = &plane;
    }
  }
  if (ground != nullptr) {
    ground->kind = msg::PlaneKind::kGround;
  }
  return planes;
}

}  // namespace blockmap::bench
