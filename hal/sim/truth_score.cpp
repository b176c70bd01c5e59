#include "blockmap/hal/sim/truth_score.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"
#include "blockmap/planes/polygon.hpp"

namespace blockmap::hal::sim {
namespace {

double median(std::vector<double> values) {
  if (values.empty()) {
    return 0.0;
  }
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

// The true position at `t_s`, between the samples around it; false outside their span.
bool true_position_at(std::span<const TimedPosition> truth, double t_s, Eigen::Vector3d& out) {
  const auto after =
      std::lower_bound(truth.begin(), truth.end(), t_s,
                       [](const TimedPosition& sample, double t) { return sample.t_s < t; });
  if (after == truth.end() || (after == truth.begin() && after->t_s > t_s)) {
    return false;
  }
  if (after->t_s == t_s || after == truth.begin()) {
    out = after->position_m;
    return true;
  }
  const TimedPosition& before = *(after - 1);
  const double w = (t_s - before.t_s) / (after->t_s - before.t_s);
  out = (1.0 - w) * before.position_m + w * after->position_m;
  return true;
}

}  // namespace

double PlaneScore::recall() const noexcept {
  return faces_considered == 0
             ? 1.0
             : static_cast<double>(faces_found) / static_cast<double>(faces_considered);
}

double PlaneScore::precision() const noexcept {
  return structural_planes == 0
             ? 1.0
             : static_cast<double>(structural_real) / static_cast<double>(structural_planes);
}

Eigen::Vector3d face_centre(const TruthFace& face) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& corner : face.corners_m) {
    centre += corner;
  }
  return centre / static_cast<double>(std::max<std::size_t>(face.corners_m.size(), 1));
}

FaceMatch match_face(const TruthFace& face, const msg::PlanePatch& plane,
                     const PlaneMatchLimits& limits) {
  FaceMatch match;
  const double cos_angle = std::min(1.0, std::abs(face.normal.dot(plane.normal)));
  match.angle_deg = std::acos(cos_angle) / kRadiansPerDegree;
  const Eigen::Vector3d centre = face_centre(face);
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

bool structural(msg::PlaneKind kind) noexcept {
  return kind == msg::PlaneKind::kWall || kind == msg::PlaneKind::kRoof ||
         kind == msg::PlaneKind::kGround;
}

PlaneScore score_planes(std::span<const TruthFace> faces, std::span<const msg::PlanePatch> planes,
                        const PlaneMatchLimits& limits) {
  PlaneScore score;
  std::vector<double> angles;
  std::vector<double> offsets;
  for (const TruthFace& face : faces) {
    if (face.returns < limits.min_face_returns) {
      continue;
    }
    ++score.faces_considered;
    const bool wall = face.kind == SurfaceKind::kWall;
    score.walls_considered += wall ? 1U : 0U;
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
      score.walls_found += wall ? 1U : 0U;
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
    const bool real = std::any_of(faces.begin(), faces.end(), [&](const TruthFace& face) {
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

double footprint_iou(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b,
                     double cell_m) {
  if (a.size() < 3 || b.size() < 3) {
    return 0.0;
  }
  Eigen::Vector2d lo = a[0];
  Eigen::Vector2d hi = a[0];
  for (const auto polygon : {a, b}) {
    for (const Eigen::Vector2d& p : polygon) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  std::size_t both = 0;
  std::size_t either = 0;
  for (double y = lo.y() + 0.5 * cell_m; y < hi.y(); y += cell_m) {
    for (double x = lo.x() + 0.5 * cell_m; x < hi.x(); x += cell_m) {
      const bool in_a = planes::inside_polygon({x, y}, a);
      const bool in_b = planes::inside_polygon({x, y}, b);
      both += (in_a && in_b) ? 1U : 0U;
      either += (in_a || in_b) ? 1U : 0U;
    }
  }
  return either == 0 ? 0.0 : static_cast<double>(both) / static_cast<double>(either);
}

Eigen::Vector3d PathAlignment::apply(const Eigen::Vector3d& point_m) const {
  return Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) * point_m + shift_m;
}

Eigen::Vector2d PathAlignment::apply(const Eigen::Vector2d& point_m) const {
  return Eigen::Rotation2Dd(yaw_rad) * point_m + shift_m.head<2>();
}

msg::PlanePatch PathAlignment::apply(const msg::PlanePatch& plane) const {
  msg::PlanePatch out = plane;
  out.normal = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) * plane.normal;
  out.centroid_m = apply(plane.centroid_m);
  out.d_m = out.normal.dot(out.centroid_m);
  for (std::size_t i = 0; i < plane.polygon_size; ++i) {
    out.polygon_m[i] = apply(plane.polygon_m[i]);
  }
  return out;
}

PathAlignment align_path(std::span<const TimedPosition> estimated,
                         std::span<const TimedPosition> truth) {
  std::vector<Eigen::Vector3d> from;
  std::vector<Eigen::Vector3d> to;
  for (const TimedPosition& pose : estimated) {
    Eigen::Vector3d true_m;
    if (true_position_at(truth, pose.t_s, true_m)) {
      from.push_back(pose.position_m);
      to.push_back(true_m);
    }
  }
  PathAlignment alignment;
  alignment.pairs = from.size();
  if (from.empty()) {
    return alignment;
  }
  const auto count = static_cast<double>(from.size());
  Eigen::Vector3d from_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d to_mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    from_mean += from[i] / count;
    to_mean += to[i] / count;
  }
  // In the plane the least-squares turn has a closed form: the angle of the summed cross and
  // dot products of the centred pairs.
  double dot = 0.0;
  double cross = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const Eigen::Vector2d a = (from[i] - from_mean).head<2>();
    const Eigen::Vector2d b = (to[i] - to_mean).head<2>();
    dot += a.dot(b);
    cross += a.x() * b.y() - a.y() * b.x();
  }
  alignment.yaw_rad = std::atan2(cross, dot);
  alignment.offset_m = (from_mean - to_mean).head<2>();
  alignment.shift_m =
      to_mean - Eigen::AngleAxisd(alignment.yaw_rad, Eigen::Vector3d::UnitZ()) * from_mean;
  std::vector<double> errors_m;
  double sum_sq_m2 = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const double error_m = (alignment.apply(from[i]) - to[i]).head<2>().norm();
    errors_m.push_back(error_m);
    sum_sq_m2 += error_m * error_m;
    alignment.max_m = std::max(alignment.max_m, error_m);
  }
  alignment.rms_m = std::sqrt(sum_sq_m2 / count);
  alignment.median_m = median(errors_m);
  return alignment;
}

}  // namespace blockmap::hal::sim
