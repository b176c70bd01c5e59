// Issue 5's accuracy on the simulated worlds: the cloud every laser return makes along the
// true trajectory, scored against the world's truth faces.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <numbers>
#include <string>

#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/sim/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "long_test.hpp"
#include "plane_truth.hpp"

namespace blockmap::planes {
namespace {

// Under QEMU and sanitizers the worlds are driven for their first minute only: the same
// checks, fewer faces.
#if defined(BLOCKMAP_QUICK_WORLDS)
constexpr double kDurationS = 60.0;
constexpr std::size_t kMaxSamples = std::size_t{1} << 18;
#else
constexpr double kDurationS = 0.0;                         // the whole path
constexpr std::size_t kMaxSamples = std::size_t{1} << 20;  // partial: 580,000 samples
#endif

struct WorldRun {
  testing::PlaneScore score;
  std::size_t planes = 0;
};

PlanesConfig city_config() {
  PlanesConfig config;
  config.max_samples = kMaxSamples;
  return config;
}

// The world turned as a whole: the ground slopes and the walls lean.
struct WorldTilt {
  double about_x_deg = 0.0;
  double about_y_deg = 0.0;
};

void tilt(hal::sim::TruthCloud& cloud, const WorldTilt& tilt) {
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

// Why each missed face was missed: the plane nearest to it in direction and offset, if any.
void print_missed_faces(std::span<const hal::sim::TruthFace> faces,
                        std::span<const msg::PlanePatch> planes, const testing::PlaneScore& s) {
  for (const int id : s.missed_faces) {
    const auto face = std::find_if(faces.begin(), faces.end(),
                                   [id](const hal::sim::TruthFace& f) { return f.id == id; });
    if (face == faces.end()) {
      continue;
    }
    const msg::PlanePatch* nearest = nullptr;
    testing::FaceMatch nearest_match;
    for (const msg::PlanePatch& plane : planes) {
      const testing::FaceMatch match = testing::match_face(*face, plane, {});
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

WorldRun detect_in_world(const std::string& world, hal::sim::PoseNoise noise = {},
                         const WorldTilt& world_tilt = {},
                         const PlanesConfig& config = city_config(), std::uint64_t seed = 3) {
  hal::sim::SimOptions options;
  options.seed = seed;
  options.max_duration_s = kDurationS;
  hal::sim::TruthCloud cloud = hal::sim::simulate_truth_cloud(
      hal::sim::load_world(world), hal::sim::load_robot("paper_rmp"), options, noise);
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
  print_missed_faces(cloud.faces, planes, s);
  return run;
}

void expect_issue_accuracy(const WorldRun& run) {
  const testing::PlaneScore& s = run.score;
  EXPECT_GE(s.faces_considered, 3u);  // usc_block after one minute: two walls and the ground
  EXPECT_GE(s.recall(), 0.95);
  EXPECT_GE(s.precision(), 0.95);
  EXPECT_LE(s.median_angle_deg, 0.5);
  EXPECT_LE(s.median_offset_m, 0.03);
  EXPECT_EQ(s.faces_reported_twice, 0u);
}

TEST(PlaneAccuracy, UscBlock) {
  BLOCKMAP_LONG_TEST();
  expect_issue_accuracy(detect_in_world("usc_block"));
}

TEST(PlaneAccuracy, Benning) {
  BLOCKMAP_LONG_TEST();
  expect_issue_accuracy(detect_in_world("benning"));
}

TEST(PlaneAccuracy, Partial) {
  expect_issue_accuracy(detect_in_world("partial"));
}

// Robustness (issue 5): the world turned so that the ground slopes 3 deg and the walls lean
// 1 deg (normals along y) and 3 deg (normals along x): the searched orientations reach 5 deg
// from vertical and horizontal, and the labels follow.
constexpr WorldTilt kTilt{1.0, 3.0};

void expect_robust_recall(const std::string& world) {
  const WorldRun run = detect_in_world(world, {}, kTilt);
  EXPECT_GE(run.score.faces_considered, 3u);
  EXPECT_GE(run.score.recall(), 0.90);
  EXPECT_GE(run.score.precision(), 0.95);
  EXPECT_EQ(run.score.faces_reported_twice, 0u);
}

TEST(PlaneRobustness, UscBlockWithSlopedGroundAndLeaningWalls) {
  BLOCKMAP_LONG_TEST();
  expect_robust_recall("usc_block");
}

// The sanitized and QEMU trees check the tilted usc_block only: the same code, minutes less.
TEST(PlaneRobustness, BenningWithSlopedGroundAndLeaningWalls) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive the tilted benning";
#endif
  expect_robust_recall("benning");
}

TEST(PlaneRobustness, PartialWithSlopedGroundAndLeaningWalls) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive the tilted partial world";
#endif
  expect_robust_recall("partial");
}

// Pose noise (issue 5 asks for 0.5 deg / 5 cm): every scan of every laser gets its own error,
// 0.5 deg about each axis and 5 cm along each, so a wall 15 m away is a slab about 0.13 m
// thick. usc_block and benning meet the issue's recall (benning's glimpsed east and west
// sides through the corner look); partial does not (docs/planes.md has the table).
constexpr hal::sim::PoseNoise kScanPoseNoise{0.5 * std::numbers::pi / 180.0, 0.05, 0.0};

// The first minute of usc_block (the sanitized and QEMU trees) has three faces; its ground,
// seen edge-on through 0.5 deg of pitch noise, fits a few tenths of a degree off, on one
// platform's rounding and not another's. The whole path is the test.
TEST(PlaneRobustness, UscBlockWithPoseNoise) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive the whole of usc_block with pose noise";
#endif
  const WorldRun run = detect_in_world("usc_block", kScanPoseNoise);
  EXPECT_GE(run.score.faces_considered, 3u);
  EXPECT_GE(run.score.recall(), 0.90);
  EXPECT_GE(run.score.precision(), 0.95);
  EXPECT_EQ(run.score.faces_reported_twice, 0u);
}

// The issue's three at once: pose noise on a world whose ground slopes 3 deg and whose walls
// lean 1 and 3 deg. Near the roof two wall fragments of about 130 samples, fitted 16 and 18
// deg off their walls inside the walls' noise slabs, came out as walls of their own until
// such tails could be 25 deg off (PlaneMerger, within_noise_slab).
TEST(PlaneRobustness, UscBlockWithPoseNoiseOnATiltedWorld) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive the whole of usc_block with pose noise";
#endif
  const WorldRun run = detect_in_world("usc_block", kScanPoseNoise, kTilt);
  EXPECT_GE(run.score.faces_considered, 3u);
  EXPECT_GE(run.score.recall(), 0.90);
  EXPECT_GE(run.score.precision(), 0.95);
  EXPECT_EQ(run.score.faces_reported_twice, 0u);
}

// The issue's 90 %: 27 of 29 faces, 27 of 28 planes real. The corner look finds the sides
// only glimpsed and the north L's notch (a step back from its east side); its ground (seen only
// by the level laser, at grazing range) and a side hidden behind a hedge are lost
// (docs/planes.md, Robustness, says why).
TEST(PlaneRobustness, PartialWithPoseNoise) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive partial with pose noise";
#endif
  const WorldRun run = detect_in_world("partial", kScanPoseNoise);
  EXPECT_GE(run.score.recall(), 0.90);
  EXPECT_GE(run.score.precision(), 0.95);
  EXPECT_EQ(run.score.faces_reported_twice, 0u);
}

// The issue's 90 % recall: 30 of 32 faces, 30 of 32 planes real. Five of its east and west
// sides are only glimpsed; the corner look finds three (docs/planes.md, Robustness).
TEST(PlaneRobustness, BenningWithPoseNoise) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning with pose noise";
#endif
  const WorldRun run = detect_in_world("benning", kScanPoseNoise);
  EXPECT_GE(run.score.recall(), 0.90);
  EXPECT_GE(run.score.precision(), 0.90);
  EXPECT_EQ(run.score.faces_reported_twice, 0u);
}

// The figures of docs/planes.md over seeds 1-6 (each seed draws the world's clutter, the lasers'
// noise and the pose errors), with and without the corner look: a few minutes, so on demand
// (--gtest_also_run_disabled_tests). It holds what every seed reached on 2026-11-25.
TEST(PlaneRobustness, DISABLED_BenningAndPartialWithPoseNoiseOverSeeds1To6) {
  for (const bool corner_look : {false, true}) {
    PlanesConfig config = city_config();
    config.corner_look = corner_look;
    for (std::uint64_t seed = 1; seed <= 6; ++seed) {
      std::printf("corner look %s, seed %llu\n", corner_look ? "on" : "off",
                  static_cast<unsigned long long>(seed));
      const WorldRun benning = detect_in_world("benning", kScanPoseNoise, {}, config, seed);
      const WorldRun partial = detect_in_world("partial", kScanPoseNoise, {}, config, seed);
      if (corner_look) {
        EXPECT_GE(benning.score.recall(), 0.90) << "seed " << seed;
        EXPECT_GE(benning.score.precision(), 0.90) << "seed " << seed;
        EXPECT_GE(partial.score.recall(), 0.85) << "seed " << seed;
        EXPECT_GE(partial.score.precision(), 0.85) << "seed " << seed;
      }
    }
  }
}

// The table of docs/planes.md (Robustness): each world under each pose noise, and the three
// of the issue at once (0.5 deg per scan on the tilted world). About a minute, on demand
// (--gtest_also_run_disabled_tests); it prints the table at the end.
TEST(PlaneRobustness, DISABLED_TheTableOfDocsPlanes) {
  constexpr double kDegToRad = std::numbers::pi / 180.0;
  struct Row {
    const char* name = "";
    hal::sim::PoseNoise noise;
    WorldTilt tilt;
  };
  const std::array rows{
      Row{"0.5 deg, 5 cm, per scan", kScanPoseNoise, {}},
      Row{"0.5 deg, 5 cm, drifting, 1 s", {0.5 * kDegToRad, 0.05, 1.0}, {}},
      Row{"0.5 deg, 5 cm, drifting, 10 s", {0.5 * kDegToRad, 0.05, 10.0}, {}},
      Row{"0.25 deg, 2.5 cm, per scan", {0.25 * kDegToRad, 0.025, 0.0}, {}},
      Row{"0.5 deg, 5 cm, per scan, tilted world", kScanPoseNoise, {1.0, 3.0}},
  };
  std::string table = "| noise | usc_block | benning | partial |\n|---|---|---|---|\n";
  for (const Row& row : rows) {
    table += std::string("| ") + row.name;
    for (const char* world : {"usc_block", "benning", "partial"}) {
      const testing::PlaneScore s = detect_in_world(world, row.noise, row.tilt).score;
      table += " | " + std::to_string(s.faces_found) + "/" + std::to_string(s.faces_considered) +
               ", " + std::to_string(s.structural_real) + "/" + std::to_string(s.structural_planes);
      if (s.faces_reported_twice > 0) {
        table += ", " + std::to_string(s.faces_reported_twice) + " twice";
      }
    }
    table += " |\n";
  }
  std::printf("%s", table.c_str());
}

}  // namespace
}  // namespace blockmap::planes
