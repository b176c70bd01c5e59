// The batch detector on a simulated world's truth cloud (every laser return along the true
// trajectory, with pose noise or the world tilted as asked), scored against the truth faces:
// shared by the plane accuracy tests (tests/planes) and the accuracy tables
// (tests/bench/bench_accuracy.cpp).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numbers>
#include <span>
#include <string>

#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "plane_truth.hpp"

namespace blockmap::planes {

// Under QEMU and sanitizers the worlds are driven for their first minute only: the same
// checks, fewer faces.
#if defined(BLOCKMAP_QUICK_WORLDS)
inline constexpr double kDurationS = 60.0;
inline constexpr std::size_t kMaxSamples = std::size_t{1} << 18;
#else
inline constexpr double kDurationS = 0.0;                         // the whole path
inline constexpr std::size_t kMaxSamples = std::size_t{1} << 20;  // partial: 580,000 samples
#endif

struct WorldRun {
  testing::PlaneScore score;
  std::size_t planes = 0;
};

inline PlanesConfig city_config() {
  PlanesConfig config;
  config.max_samples = kMaxSamples;
  return config;
}

// The world turned as a whole: the ground slopes and the walls lean.
struct WorldTilt {
  double about_x_deg = 0.0;
  double about_y_deg = 0.0;
};

inline void tilt(hal::sim::TruthCloud& cloud, const WorldTilt& tilt) {
  constexpr double kDegToRad = std::numbers::pi / 180.0;
  const Eigen::Matrix3d rotation =
      (Eigen::AngleAxisd(tilt.about_x_deg * kDegToRad, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(tilt.about_y_deg * kDegToRad, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  for (Eigen::Vector3f& p : cloud.points_m) {
    p = (rotation * p.cast<double>()).cast<float>();
  }
  // A rotation about the origin keeps each face's distance d from it.
  for (hal::sim::TruthFace& face : cloud.faces) {
    face.normal = rotation * face.normal;
    for (hal::sim::Vec3& corner : face.corners_m) {
      corner = rotation * corner;
    }
  }
}

inline WorldRun detect_in_world(const std::string& world, hal::sim::PoseNoise noise = {},
                                const WorldTilt& world_tilt = {},
                                const PlanesConfig& config = city_config(),
                                std::uint64_t seed = 3) {
  hal::sim::SimOptions options;
  options.seed = seed;
  options.max_duration_s = kDurationS;
  hal::sim::TruthCloud cloud = hal::sim::simulate_truth_cloud(
      hal::sim::load_world(world), hal::config::load_robot("paper_rmp"), options, noise);
  tilt(cloud, world_tilt);
  Arena arena(PlaneDetector::arena_budget_bytes(config));
  PlaneDetector detector;
  detector.init(arena, config);
  arena.seal();
  detector.add_points(cloud.points_m);
  const auto planes = detector.detect();
  EXPECT_EQ(detector.stats().overflows, 0u);
  EXPECT_EQ(detector.stats().points_dropped, 0u);
  WorldRun run{testing::score_planes(cloud.faces, planes), planes.size()};
  const testing::PlaneScore& s = run.score;
  std::printf(
      "%s: %zu points, %zu planes; faces %zu/%zu found, structural %zu/%zu real, %zu twice, "
      "median %.3f deg %.4f m\n",
      world.c_str(), cloud.points_m.size(), planes.size(), s.faces_found, s.faces_considered,
      s.structural_real, s.structural_planes, s.faces_reported_twice, s.median_angle_deg,
      s.median_offset_m);
  for (const msg::PlanePatch& plane : planes) {
    const bool is_false =
        std::find(s.false_planes.begin(), s.false_planes.end(), plane.id) != s.false_planes.end();
    if (is_false || testing::structural(plane.kind)) {
      std::printf(
          "  %s plane %u %s n (%.3f %.3f %.3f) d %.2f support %.0f rmse %.3f centroid (%.1f %.1f "
          "%.1f)\n",
          is_false ? "FALSE" : "ok", plane.id, std::string(msg::to_string(plane.kind)).c_str(),
          plane.normal.x(), plane.normal.y(), plane.normal.z(), plane.d_m, plane.support,
          plane.rmse_m, plane.centroid_m.x(), plane.centroid_m.y(), plane.centroid_m.z());
    }
  }
  const DetectionStats& stats = detector.stats();
  std::printf(
      "  samples %llu: planar %llu, linear %llu, scattered %llu; sections %llu searched, "
      "%llu section planes\n",
      static_cast<unsigned long long>(stats.samples),
      static_cast<unsigned long long>(stats.planar_samples),
      static_cast<unsigned long long>(stats.linear_samples),
      static_cast<unsigned long long>(stats.scattered_samples),
      static_cast<unsigned long long>(stats.sections_searched),
      static_cast<unsigned long long>(stats.section_planes));
  std::printf("  surface noise %.4f m\n", stats.surface_noise_m);
  testing::print_missed_faces(cloud.faces, planes, s);
  return run;
}

}  // namespace blockmap::planes
