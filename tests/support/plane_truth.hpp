// Scoring detected planes against a simulated world's truth faces, the way issue 5 defines
// accuracy: a face is found by a plane within 3 degrees, 0.15 m at the face centre, whose
// extent overlaps the face.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "blockmap/hal/sim/scene.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/polygon.hpp"

namespace blockmap::testing {

struct PlaneMatchLimits {
  double max_angle_deg = 3.0;
  double max_offset_m = 0.15;
  std::uint64_t min_face_returns = 200;
};

struct PlaneScore {
  std::size_t faces_considered = 0;  // faces with enough returns
  std::size_t faces_found = 0;
  std::size_t structural_planes = 0;  // reported wall, roof or ground
  std::size_t structural_real = 0;    // of those, matching some face
  std::size_t faces_reported_twice = 0;
  double median_angle_deg = 0.0;  // over found faces, best match each
  double median_offset_m = 0.0;
  std::vector<int> missed_faces;            // ids
  std::vector<std::uint32_t> false_planes;  // ids of structural planes matching no face

  [[nodiscard]] double recall() const {
    return faces_considered == 0
               ? 1.0
               : static_cast<double>(faces_found) / static_cast<double>(faces_considered);
  }
  [[nodiscard]] double precision() const {
    return structural_planes == 0
               ? 1.0
               : static_cast<double>(structural_real) / static_cast<double>(structural_planes);
  }
};

struct FaceMatch {
  bool matches = false;
  double angle_deg = 0.0;
  double offset_m = 0.0;
};

inline FaceMatch match_face(const hal::sim::TruthFace& face, const msg::PlanePatch& plane,
                            const PlaneMatchLimits& limits) {
  FaceMatch match;
  const double cos_angle = std::min(1.0, std::abs(face.normal.dot(plane.normal)));
  match.angle_deg = std::acos(cos_angle) * 180.0 / std::numbers::pi;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& corner : face.corners_m) {
    centre += corner;
  }
  centre /= static_cast<double>(face.corners_m.size());
  match.offset_m = std::abs(plane.normal.dot(centre) - plane.d_m);
  if (match.angle_deg >= limits.max_angle_deg || match.offset_m >= limits.max_offset_m) {
    return match;
  }
  // Extents overlap on the face's plane.
  const auto [u, v] = planes::plane_basis(face.normal);
  std::vector<Eigen::Vector2d> face_points;
  std::vector<Eigen::Vector2d> plane_points;
  for (const Eigen::Vector3d& corner : face.corners_m) {
    face_points.emplace_back(u.dot(corner - centre), v.dot(corner - centre));
  }
  for (std::size_t i = 0; i < plane.polygon_size; ++i) {
    const Eigen::Vector3d p = plane.polygon_m[i] - centre;
    plane_points.emplace_back(u.dot(p), v.dot(p));
  }
  std::vector<Eigen::Vector2d> face_hull(face_points.size() + 1);
  std::vector<Eigen::Vector2d> plane_hull(plane_points.size() + 1);
  face_hull.resize(planes::convex_hull(face_points, face_hull));
  plane_hull.resize(planes::convex_hull(plane_points, plane_hull));
  match.matches = planes::convex_polygon_gap(face_hull, plane_hull) <= 0.0;
  return match;
}

inline bool structural(msg::PlaneKind kind) {
  return kind == msg::PlaneKind::kWall || kind == msg::PlaneKind::kRoof ||
         kind == msg::PlaneKind::kGround;
}

inline double median(std::vector<double> values) {
  if (values.empty()) {
    return 0.0;
  }
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

inline PlaneScore score_planes(std::span<const hal::sim::TruthFace> faces,
                               std::span<const msg::PlanePatch> planes,
                               const PlaneMatchLimits& limits = {}) {
  PlaneScore score;
  std::vector<double> angles;
  std::vector<double> offsets;
  for (const hal::sim::TruthFace& face : faces) {
    if (face.returns < limits.min_face_returns) {
      continue;
    }
    ++score.faces_considered;
    bool found = false;
    FaceMatch best;
    std::size_t structural_matches = 0;
    for (const msg::PlanePatch& plane : planes) {
      const FaceMatch match = match_face(face, plane, limits);
      if (!match.matches) {
        continue;
      }
      structural_matches += structural(plane.kind) ? 1U : 0U;
      if (!found || match.angle_deg < best.angle_deg) {
        best = match;
      }
      found = true;
    }
    if (found) {
      ++score.faces_found;
      angles.push_back(best.angle_deg);
      offsets.push_back(best.offset_m);
    } else {
      score.missed_faces.push_back(face.id);
    }
    score.faces_reported_twice += structural_matches > 1 ? 1 : 0;
  }
  for (const msg::PlanePatch& plane : planes) {
    if (!structural(plane.kind)) {
      continue;
    }
    ++score.structural_planes;
    const bool real = std::any_of(faces.begin(), faces.end(), [&](const hal::sim::TruthFace& face) {
      return match_face(face, plane, limits).matches;
    });
    if (real) {
      ++score.structural_real;
    } else {
      score.false_planes.push_back(plane.id);
    }
  }
  score.median_angle_deg = median(angles);
  score.median_offset_m = median(offsets);
  return score;
}

}  // namespace blockmap::testing
