// A map against a simulated run's truth: planes against the faces (a face with at least
// min_face_returns returns is found when a plane lies within max_angle_deg and max_offset_m at
// its centre and their extents overlap), footprints against the buildings (intersection over
// union), and the estimated path laid onto the true one by the least-squares rigid motion (a
// turn about the vertical, a shift; no scale), as SLAM benchmarks score the absolute
// trajectory error. No mapper can place walls better than its receiver in absolute terms: a
// map is scored after that motion, and the motion's shift is reported beside it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "blockmap/hal/sim/scene.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::hal::sim {

struct PlaneMatchLimits {
  double max_angle_deg = 3.0;
  double max_offset_m = 0.15;
  std::uint64_t min_face_returns = 200;
};

struct PlaneScore {
  std::size_t faces_considered = 0;  // faces with enough returns
  std::size_t faces_found = 0;
  std::size_t walls_considered = 0;  // of those, walls
  std::size_t walls_found = 0;
  std::size_t structural_planes = 0;  // reported wall, roof or ground
  std::size_t structural_real = 0;    // of those, matching some face
  std::size_t faces_reported_twice = 0;
  double median_angle_deg = 0.0;  // over found faces, best match each
  double median_offset_m = 0.0;
  std::vector<int> missed_faces;            // ids
  std::vector<std::uint32_t> false_planes;  // ids of structural planes matching no face

  [[nodiscard]] double recall() const noexcept;
  [[nodiscard]] double precision() const noexcept;
};

struct FaceMatch {
  bool matches = false;
  double angle_deg = 0.0;
  double offset_m = 0.0;
};

[[nodiscard]] Eigen::Vector3d face_centre(const TruthFace& face);
[[nodiscard]] FaceMatch match_face(const TruthFace& face, const msg::PlanePatch& plane,
                                   const PlaneMatchLimits& limits);
// A wall, roof or ground: a plane the map claims is a surface of the world.
[[nodiscard]] bool structural(msg::PlaneKind kind) noexcept;
[[nodiscard]] PlaneScore score_planes(std::span<const TruthFace> faces,
                                      std::span<const msg::PlanePatch> planes,
                                      const PlaneMatchLimits& limits = {});

// The intersection over union of two simple polygons, rasterized every cell_m (exact enough
// for the 0.8-0.95 thresholds it is read against, and right for a concave L or T).
[[nodiscard]] double footprint_iou(std::span<const Eigen::Vector2d> a,
                                   std::span<const Eigen::Vector2d> b, double cell_m = 0.05);

// A position of a path at a time, in the local frame.
struct TimedPosition {
  double t_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
};

// The rigid motion that lays an estimated path onto the true one: p' = R(yaw) p + shift.
struct PathAlignment {
  double yaw_rad = 0.0;
  Eigen::Vector3d shift_m = Eigen::Vector3d::Zero();
  std::size_t pairs = 0;  // estimated positions with a true one at their time
  // Where the estimated path sits, on average: its centroid less the true path's (east,
  // north). The shift above depends on where the frame's origin is, through the turn; this
  // does not, and is what a receiver's mean error moves.
  Eigen::Vector2d offset_m = Eigen::Vector2d::Zero();
  // The estimated path after the motion, against the true one (horizontal distances).
  double rms_m = 0.0;
  double median_m = 0.0;
  double max_m = 0.0;

  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& point_m) const;
  [[nodiscard]] Eigen::Vector2d apply(const Eigen::Vector2d& point_m) const;
  [[nodiscard]] msg::PlanePatch apply(const msg::PlanePatch& plane) const;
};

// Each estimated position paired with the true path at its time (linearly between the true
// samples, which are sorted by time; positions outside the true path's span are left out),
// and the turn about the vertical and the shift that minimize the pairs' squared horizontal
// distances (Umeyama's closed form without scale); the height shift is the mean difference.
[[nodiscard]] PathAlignment align_path(std::span<const TimedPosition> estimated,
                                       std::span<const TimedPosition> truth);

}  // namespace blockmap::hal::sim
