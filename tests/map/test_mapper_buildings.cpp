// The mapper's buildings over the simulated robot against the world's footprints: with the
// filter's poses drawn late, with an RTK receiver, and with the whole run's rigid path.
#include <gtest/gtest.h>

#include "long_test.hpp"
#include "mapper_runs.hpp"

namespace blockmap::pipeline {
namespace {

// benning's buildings from scans drawn 30 s late (docs/buildings.md): the shapes come right
// where the live poses bent them. Measured on the whole path, seed 3: 6 of 6 shapes right,
// IoU 0.68-0.83, mean 0.76 (2026-11-25, with walls cut at a full front; drawn live: 3 of 6,
// 0.33-0.80, mean 0.65). The issue's 0.85 still waits on the smoothed path's metre of
// absolute error.
TEST(MapperSim, BenningBuildingsWithLaggedFilterPoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning with the lagged poses";
#endif
  const MapperRun run = map_world({.world = "benning", .pose_lag_s = 30.0});
  std::size_t right_shapes = 0;
  double iou_sum = 0.0;
  const hal::sim::World world = hal::sim::load_world("benning");
  const std::vector<BuildingMatch> matches = building_matches(run, world, "benning, lagged");
  for (const BuildingMatch& match : matches) {
    right_shapes += match.shape == match.truth_shape ? 1U : 0U;
    iou_sum += match.iou;
    EXPECT_GT(match.iou, 0.62) << "truth building " << match.truth_id;
  }
  ASSERT_EQ(matches.size(), 6u);
  EXPECT_GE(right_shapes, 5u);
  EXPECT_GT(iou_sum / static_cast<double>(matches.size()), 0.74);
  EXPECT_EQ(run.counters.scans_refused_full, 0u);
}

// With an RTK receiver the filter's live poses give benning's buildings as the issue asks of
// fully seen ones (IoU 0.85 with the particle filter's poses): seed 3, 6 of 6 shapes right,
// IoU 0.946-0.992 (docs/buildings.md; over seeds 1-10, 59 of 60, mean 0.966).
TEST(MapperSim, BenningBuildingsWithAnRtkReceiverMeetTheIssue) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const MapperRun run = map_world({.world = "benning", .robot = "paper_rmp_rtk"});
  const hal::sim::World world = hal::sim::load_world("benning");
  const std::vector<BuildingMatch> matches = building_matches(run, world, "benning, RTK");
  ASSERT_EQ(matches.size(), 6u);
  for (const BuildingMatch& match : matches) {
    EXPECT_EQ(match.shape, match.truth_shape) << "truth building " << match.truth_id;
    EXPECT_GE(match.iou, 0.85) << "truth building " << match.truth_id;
  }
}

// The rigid path (docs/localize.md, The whole path at once): the same benning run with the
// final planes moved by the whole run's solved path (the default; here against the same run
// without it). Seed 1 (2026-12-03): the keyframes' poses 1.96 m RMS off as drawn, 0.99 m as
// solved; the buildings' mean IoU 0.649 -> 0.779, shapes right 5 -> 6 of 6.
TEST(MapperSim, BenningBuildingsWithTheRigidPath) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning with the rigid path";
#endif
  const hal::sim::World world = hal::sim::load_world("benning");
  const auto mean_iou = [&](const MapperRun& run, const char* label, std::size_t& right) {
    double sum = 0.0;
    const std::vector<BuildingMatch> matches = building_matches(run, world, label);
    for (const BuildingMatch& match : matches) {
      sum += match.iou;
      right += match.shape == match.truth_shape ? 1U : 0U;
    }
    return sum / static_cast<double>(matches.size());
  };
  const MapperRun live = map_world({.world = "benning", .seed = 1, .rigid_path = RigidPath::kOff});
  const MapperRun rigid = map_world({.world = "benning", .seed = 1, .rigid_path = RigidPath::kOn});
  std::size_t live_right = 0;
  std::size_t rigid_right = 0;
  const double live_iou = mean_iou(live, "benning, live", live_right);
  const double rigid_iou = mean_iou(rigid, "benning, rigid path", rigid_right);
  EXPECT_GT(rigid_iou, live_iou + 0.04);
  EXPECT_GE(rigid_right, live_right);
  // Off the truth by the receiver's error averaged over the run (scripts/gps-bound), its
  // shape the odometry's between fixes: over seeds 1-10 the solved path is 0.44-0.91 of the
  // drawn one and its shape 0.35-0.86 (docs/localize.md; seed 1, 2026-12-05: 0.73 and 0.66).
  EXPECT_LT(rigid.solved_rms_m, 0.8 * rigid.drawn_rms_m);
  EXPECT_LT(rigid.solved_shape_m, 0.75 * rigid.drawn_shape_m);
  EXPECT_GT(rigid.rigid_path.planes_moved, rigid.final_planes.size() / 2);
  EXPECT_EQ(rigid.rigid_path.fixes_dropped, 0u);
  expect_stream_gives_final_list(rigid);
}

// Twice round usc_block every wall is seen on two laps: the mapper pairs each wall of the
// second lap with its drawing on the first (the same face, overlapping, within 2 m and 5
// degrees), and ties the two laps' keyframes. Seed 1 (2026-12-06, the map drawn in the
// matcher's own frame): 6 ties; the matched path is 0.23 m off the truth over both laps and
// the solved path's shape 0.31 m, 0.32 m with max_ties = 0. (Before the matcher kept its own
// frame, 34 ties took the shape from 0.84 m to 0.54 m: the laps are one block already.)
TEST(MapperSim, UscBlockTwiceRoundTiesTheWallsOfOneLapToTheOther) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block twice round";
#endif
  const MapperRun run =
      map_world({.world = "usc_block", .seed = 1, .rigid_path = RigidPath::kOn, .laps = 2});
  std::printf("%zu ties, %llu dropped; solved path %.2f m RMS, shape %.2f m\n", run.ties,
              static_cast<unsigned long long>(run.ties_dropped), run.solved_rms_m,
              run.solved_shape_m);
  EXPECT_GE(run.ties, 4u);
  EXPECT_EQ(run.ties_dropped, 0u);
  EXPECT_LT(run.solved_shape_m, 0.45);
  expect_stream_gives_final_list(run);
}

}  // namespace
}  // namespace blockmap::pipeline
