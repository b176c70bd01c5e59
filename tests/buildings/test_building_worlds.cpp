// Building fitting's accuracy on the simulated worlds: the planes of the cloud every laser return
// makes along the true trajectory, fitted to buildings and scored against the world's footprints.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "building_world_runs.hpp"
#include "footprint_score.hpp"

namespace blockmap::buildings {
namespace {

// partial: north of the street a rect, an L and a T each miss their back (one wall never
// seen); south of it a rect and a T, turned half way round, and an L turned a quarter, miss
// their back and have a hedge in front of their east side (two walls never seen). Each comes
// out with its shape and the IoU.
TEST(BuildingWorlds, PartialBuildingsAreCompletedFromTheirSeenWalls) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive partial to the end";
#endif
  const std::vector<BuildingMatch> matches = fit_world("partial", 3);
  ASSERT_EQ(matches.size(), 6u);
  for (const BuildingMatch& match : matches) {
    EXPECT_TRUE(completed(match)) << "truth building " << match.truth_id << ": " << match.shape
                                  << ", IoU " << match.iou;
  }
}

// Buildings the robot drove around: every wall seen, IoU >= 0.95 with true poses.
void expect_fully_seen(const std::string& world) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive the worlds to the end";
#endif
  for (const BuildingMatch& match : fit_world(world, 3)) {
    EXPECT_EQ(match.shape, match.truth_shape) << "truth building " << match.truth_id;
    EXPECT_GE(match.iou, 0.95) << "truth building " << match.truth_id;
  }
}

TEST(BuildingWorlds, UscBlockFullySeen) {
  expect_fully_seen("usc_block");
}

TEST(BuildingWorlds, BenningFullySeen) {
  expect_fully_seen("benning");
}

}  // namespace
}  // namespace blockmap::buildings
