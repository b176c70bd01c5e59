// Plane detection takes everything at init: adding points and detecting planes allocate
// nothing, however many points, sections and planes there are.
#include <gtest/gtest.h>

#include <numbers>
#include <random>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "memory_assertions.hpp"

namespace blockmap::planes {
namespace {

TEST(PlanesBudget, DetectingAllocatesNothingAfterInitAndFitsItsBudget) {
  hal::sim::SimOptions options;
  options.max_duration_s = 20.0;
  const hal::sim::TruthCloud cloud = hal::sim::simulate_truth_cloud(
      hal::sim::load_world("usc_block"), hal::config::load_robot("paper_rmp"), options);
  ASSERT_GT(cloud.points_m.size(), 200'000u);
  PlanesConfig config;
  config.max_samples = 1 << 18;
  config.max_patches = 1 << 14;
  const std::size_t budget = PlaneDetector::arena_budget_bytes(config);
  Arena arena(budget);
  PlaneDetector detector;
  detector.init(arena, config);
  arena.seal();
  EXPECT_LE(arena.used_bytes(), budget);
  std::size_t planes = 0;
  EXPECT_NO_ALLOCATIONS({
    detector.add_points(cloud.points_m);
    planes = detector.detect().size();
  });
  EXPECT_GT(planes, 3u);
  // Again: a second cloud in the same detector allocates nothing either.
  EXPECT_NO_ALLOCATIONS({
    detector.clear();
    detector.add_points(cloud.points_m);
    planes = detector.detect().size();
  });
  // And a cloud blurred by pose errors, where the corner look runs after merging.
  const hal::sim::TruthCloud blurred = hal::sim::simulate_truth_cloud(
      hal::sim::load_world("usc_block"), hal::config::load_robot("paper_rmp"), options,
      hal::sim::PoseNoise{0.5 * std::numbers::pi / 180.0, 0.05, 0.0});
  EXPECT_NO_ALLOCATIONS({
    detector.clear();
    detector.add_points(blurred.points_m);
    planes = detector.detect().size();
  });
  EXPECT_GT(detector.stats().corners_looked_at, 0u);
  EXPECT_LE(detector.memory_bytes(), arena.used_bytes());
  EXPECT_EQ(arena.failed_allocations().value(), 0u);
}

TEST(PlanesBudget, TheBudgetCoversEveryConfiguration) {
  for (const double angle_bin_deg : {2.0, 5.0}) {
    for (const OrientationMode mode : {OrientationMode::kWallsAndRoofs, OrientationMode::kAny}) {
      PlanesConfig config;
      config.angle_bin_deg = angle_bin_deg;
      config.orientation_mode = mode;
      config.normal_kernel_deg = 8.0;
      config.max_samples = 4096;
      config.max_patches = 4096;
      Arena arena(PlaneDetector::arena_budget_bytes(config));
      PlaneDetector detector;
      detector.init(arena, config);  // CHECK-fails (throws in tests) when over budget
      EXPECT_EQ(arena.failed_allocations().value(), 0u);
    }
  }
}

}  // namespace
}  // namespace blockmap::planes
