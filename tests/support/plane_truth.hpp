// Scoring detected planes against a simulated world's truth faces, the way the project defines
// accuracy: a face is found by a plane within 3 degrees, 0.15 m at the face centre, whose
// extent overlaps the face.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "blockmap/hal/sim/scene.hpp"
#include "blockmap/hal/sim/truth_score.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/polygon.hpp"

namespace blockmap::testing {

// The scoring of planes against truth faces is the product's (blockmap score):
// hal/sim/truth_score.hpp. The tests read it in their own namespace.
using hal::sim::face_centre;
using hal::sim::FaceMatch;
using hal::sim::match_face;
using hal::sim::PlaneMatchLimits;
using hal::sim::PlaneScore;
using hal::sim::score_planes;
using hal::sim::structural;

// The rigid motion (a turn about the vertical through `pivot_m`, then a shift) that best lays a
// map's structural planes onto the truth faces. A map drawn with GPS-grade poses sits as far
// from the truth as the receiver's slow error: scored after this motion, what is left is the
// map's own shape (walls bent or doubled by heading drift), not where on Earth it sits.
struct MapAlignment {
  double yaw_rad = 0.0;
  Eigen::Vector3d pivot_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d shift_m = Eigen::Vector3d::Zero();
  std::size_t pairs = 0;  // plane-face pairs in the last step

  [[nodiscard]] Eigen::Matrix3d rotation() const {
    return Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& point_m) const {
    return rotation() * (point_m - pivot_m) + pivot_m + shift_m;
  }
  [[nodiscard]] msg::PlanePatch apply(const msg::PlanePatch& plane) const {
    msg::PlanePatch out = plane;
    out.normal = rotation() * plane.normal;
    out.centroid_m = apply(plane.centroid_m);
    out.d_m = out.normal.dot(out.centroid_m);
    for (std::size_t i = 0; i < plane.polygon_size; ++i) {
      out.polygon_m[i] = apply(plane.polygon_m[i]);
    }
    return out;
  }
};

// Iterated closest faces: each structural plane (as moved so far) is paired with the face of
// its kind nearest in angle and offset within the gates, which shrink from (10 deg, 3 m) to
// (4 deg, 0.6 m); the turn is the support-weighted mean angle between paired wall normals,
// the shift the support-weighted least squares of the paired offsets.
inline MapAlignment align_planes_to_faces(std::span<const hal::sim::TruthFace> faces,
                                          std::span<const msg::PlanePatch> planes) {
  MapAlignment alignment;
  double weight = 0.0;
  for (const msg::PlanePatch& plane : planes) {
    if (structural(plane.kind)) {
      alignment.pivot_m += plane.support * plane.centroid_m;
      weight += plane.support;
    }
  }
  if (weight <= 0.0) {
    return alignment;
  }
  alignment.pivot_m /= weight;
  constexpr int kSteps = 12;
  for (int step = 0; step < kSteps; ++step) {
    const double t = static_cast<double>(step) / (kSteps - 1);
    const double max_angle_rad = (10.0 - 6.0 * t) * std::numbers::pi / 180.0;
    const double max_offset_m = 3.0 - 2.4 * t;
    double turn_sum = 0.0;
    double turn_weight = 0.0;
    Eigen::Matrix3d normal_equations = Eigen::Matrix3d::Zero();
    Eigen::Vector3d right_side = Eigen::Vector3d::Zero();
    alignment.pairs = 0;
    for (const msg::PlanePatch& original : planes) {
      if (!structural(original.kind)) {
        continue;
      }
      const msg::PlanePatch plane = alignment.apply(original);
      const hal::sim::TruthFace* best = nullptr;
      double best_offset_m = max_offset_m;
      for (const hal::sim::TruthFace& face : faces) {
        const double cos_angle = std::min(1.0, std::abs(face.normal.dot(plane.normal)));
        if (std::acos(cos_angle) > max_angle_rad) {
          continue;
        }
        const double offset_m = std::abs(plane.normal.dot(face_centre(face)) - plane.d_m);
        if (offset_m < best_offset_m) {
          best = &face;
          best_offset_m = offset_m;
        }
      }
      if (best == nullptr) {
        continue;
      }
      ++alignment.pairs;
      // The face's normal, signed as the plane's.
      const Eigen::Vector3d n = best->normal.dot(plane.normal) < 0.0 ? -best->normal : best->normal;
      const double face_d_m = n.dot(face_centre(*best));
      if (std::abs(n.z()) < 0.5) {  // a wall: its azimuth turns the map
        const double turn = std::atan2(plane.normal.x() * n.y() - plane.normal.y() * n.x(),
                                       plane.normal.x() * n.x() + plane.normal.y() * n.y());
        turn_sum += plane.support * turn;
        turn_weight += plane.support;
      }
      // n . (c + s) = face_d: the shift s that puts the plane's centroid on the face.
      const double residual_m = face_d_m - n.dot(plane.centroid_m);
      normal_equations += plane.support * n * n.transpose();
      right_side += plane.support * residual_m * n;
    }
    if (turn_weight > 0.0) {
      alignment.yaw_rad += turn_sum / turn_weight;
    }
    // Directions no pair constrains stay where they are.
    normal_equations += 1e-6 * weight * Eigen::Matrix3d::Identity();
    alignment.shift_m += normal_equations.ldlt().solve(right_side);
  }
  return alignment;
}

// Why each missed face was missed: the plane nearest to it in direction and offset, if any.
inline void print_missed_faces(std::span<const hal::sim::TruthFace> faces,
                               std::span<const msg::PlanePatch> planes, const PlaneScore& s) {
  for (const int id : s.missed_faces) {
    const auto face = std::find_if(faces.begin(), faces.end(),
                                   [id](const hal::sim::TruthFace& f) { return f.id == id; });
    if (face == faces.end()) {
      continue;
    }
    const msg::PlanePatch* nearest = nullptr;
    FaceMatch nearest_match;
    for (const msg::PlanePatch& plane : planes) {
      const FaceMatch match = match_face(*face, plane, {});
      if (match.angle_deg < 10.0 &&
          (nearest == nullptr || match.offset_m < nearest_match.offset_m)) {
        nearest = &plane;
        nearest_match = match;
      }
    }
    std::printf("  MISSED face %d %s n (%.2f %.2f %.2f) d %.2f returns %llu", id,
                face->kind == hal::sim::SurfaceKind::kWall ? "wall" : "roof/ground",
                face->normal.x(), face->normal.y(), face->normal.z(), face->d_m,
                static_cast<unsigned long long>(face->returns));
    if (nearest != nullptr) {
      std::printf("; nearest plane %u %s: %.2f deg, %.3f m, support %.0f\n", nearest->id,
                  std::string(msg::to_string(nearest->kind)).c_str(), nearest_match.angle_deg,
                  nearest_match.offset_m, nearest->support);
    } else {
      std::printf("; no plane within 10 deg\n");
    }
  }
}

}  // namespace blockmap::testing
