// Issue 5's accuracy on the simulated worlds: the cloud every laser return makes along the
// true trajectory, scored against the world's truth faces.
#include <gtest/gtest.h>

#include <cstdio>
#include <numbers>
#include <string>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/sim/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "plane_truth.hpp"

namespace blockmap::planes {
namespace {

// Under QEMU and sanitizers the worlds are driven for their first minute only: the same
// checks, fewer faces.
#if defined(BLOCKMAP_QUICK_WORLDS)
constexpr double kDurationS = 60.0;
#else
constexpr double kDurationS = 0.0;  // the whole path
#endif

struct WorldRun {
  testing::PlaneScore score;
  std::size_t planes = 0;
};

WorldRun detect_in_world(const std::string& world, hal::sim::PoseNoise noise = {},
                         const PlanesConfig& config = {}) {
  hal::sim::SimOptions options;
  options.seed = 3;
  options.max_duration_s = kDurationS;
  const hal::sim::TruthCloud cloud = hal::sim::simulate_truth_cloud(
      hal::sim::load_world(world), hal::sim::load_robot("paper_rmp"), options, noise);
  Arena arena(PlaneDetector::arena_budget_bytes(config));
  PlaneDetector detector;
  detector.init(arena, config);
  arena.seal();
  detector.add_points(cloud.points_m);
  const auto planes = detector.detect();
  WorldRun run{testing::score_planes(cloud.faces, planes), planes.size()};
  const testing::PlaneScore& s = run.score;
  std::printf(
      "%s: %zu points, %zu planes; faces %zu/%zu found, structural %zu/%zu real, %zu twice, "
      "median %.3f deg %.4f m\n",
      world.c_str(), cloud.points_m.size(), planes.size(), s.faces_found, s.faces_considered,
      s.structural_real, s.structural_planes, s.faces_reported_twice, s.median_angle_deg,
      s.median_offset_m);
  return run;
}

void expect_issue_accuracy(const WorldRun& run) {
  const testing::PlaneScore& s = run.score;
  EXPECT_GE(s.faces_considered, 4u);
  EXPECT_GE(s.recall(), 0.95);
  EXPECT_GE(s.precision(), 0.95);
  EXPECT_LE(s.median_angle_deg, 0.5);
  EXPECT_LE(s.median_offset_m, 0.03);
  EXPECT_EQ(s.faces_reported_twice, 0u);
}

TEST(PlaneAccuracy, UscBlock) {
  expect_issue_accuracy(detect_in_world("usc_block"));
}

TEST(PlaneAccuracy, Benning) {
  expect_issue_accuracy(detect_in_world("benning"));
}

TEST(PlaneAccuracy, Partial) {
  expect_issue_accuracy(detect_in_world("partial"));
}

}  // namespace
}  // namespace blockmap::planes
