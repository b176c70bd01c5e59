// The mapper's planes over the simulated robot (the devices' bytes through the device layer,
// the particle filter or the true poses, the window, the detector and the registry), scored
// against the world's truth faces as the batch detector is.
#include <gtest/gtest.h>

#include "long_test.hpp"
#include "mapper_runs.hpp"

namespace blockmap::pipeline {
namespace {

TEST(MapperSim, UscBlockWithTruePosesFindsTheFaces) {
  BLOCKMAP_LONG_TEST();
  const MapperRun run = map_world({.world = "usc_block", .poses = PoseSource::kExternal});
  expect_planes_issue_accuracy(run, score(run, "usc_block, true poses"), 0.95);
  EXPECT_EQ(run.counters.scans_refused_full, 0u);
  EXPECT_EQ(run.counters.messages_late, 0u);
}

// The paper's robot with an RTK receiver (config/robots/paper_rmp_rtk.toml: the same base and
// lasers, fixes of 2 cm that say they are carrier-phase): the particle filter's live poses are
// then centimetres off, and the streamed map meets the planes issue's accuracy against truth
// as with the true poses. What keeps the paper's robot from it is its 2 m receiver, whose
// error averaged over a run no mapper removes (scripts/gps-bound; docs/localize.md, RTK
// receivers).
TEST(MapperSim, UscBlockWithAnRtkReceiverFindsTheFacesWithTheFiltersPoses) {
  BLOCKMAP_LONG_TEST();
  const MapperRun run = map_world({.world = "usc_block", .robot = "paper_rmp_rtk"});
  expect_planes_issue_accuracy(run, score(run, "usc_block, RTK receiver, filter poses"), 0.95);
  EXPECT_EQ(run.counters.fixes_rejected, 0u);
}

TEST(MapperSim, BenningWithAnRtkReceiverScoresAsWithTruePoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const MapperRun run = map_world({.world = "benning", .robot = "paper_rmp_rtk"});
  // benning's floor, as with true poses (below): three small walls beyond the window's reach.
  expect_planes_issue_accuracy(run, score(run, "benning, RTK receiver, filter poses"), 0.90);
}

// benning's floor with true poses and the default window, below the planes issue's 95 %:
// three small walls facing east (about 2,000 returns each), seen only from 30-60 m, are not
// found (docs/mapper.md); a window reaching farther finds two of them (below).
TEST(MapperSim, BenningWithTruePoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const MapperRun run = map_world({.world = "benning", .poses = PoseSource::kExternal});
  const testing::PlaneScore s = score(run, "benning, true poses");
  EXPECT_GE(s.recall(), 0.90);
  EXPECT_GE(s.precision(), 0.95);
  EXPECT_EQ(s.faces_reported_twice, 0u);
  expect_stream_gives_final_list(run);
  // The compact map: the final list as one binary record against the cloud of every point
  // the mapper took in (three float32 each, as a binary PLY holds them).
  std::vector<msg::PlaneChange> final_list;
  for (const msg::PlanePatch& plane : run.final_planes) {
    final_list.push_back({msg::PlaneChangeKind::kFinalized, plane});
  }
  const std::size_t map_bytes = hal::protocol::plane_stream::record_size(final_list);
  const std::uint64_t cloud_bytes = run.counters.points * 3 * sizeof(float);
  std::printf("benning: final plane list %zu bytes, its cloud %llu bytes: %.0f times smaller\n",
              map_bytes, static_cast<unsigned long long>(cloud_bytes),
              static_cast<double>(cloud_bytes) / static_cast<double>(map_bytes));
  EXPECT_GE(cloud_bytes, std::uint64_t{1000} * map_bytes);
}

// benning's three small walls facing east are seen only from 30-60 m: the far-reaching window
// finds them, within the default budget (docs/mapper.md, Accuracy).
TEST(MapperSim, BenningWithTruePosesAndAFarReachingWindowMeetsThePlanesIssue) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  MapperConfig config = hal::config::mapper_config_for(hal::config::load_robot("paper_rmp"));
  config.window = far_reaching_window();
  EXPECT_LE(Mapper::arena_bytes(config), std::size_t{64} << 20);
  const MapperRun run = map_with_far_reach("benning");
  expect_planes_issue_accuracy(run, score(run, "benning, true poses, far-reaching window"), 0.95);
  EXPECT_EQ(run.points_dropped_full, 0u);
}

// usc_block's walls fill more than the pool holds of an 11-tile window: its outer tiles leave
// early and the block's faces are found as with the default window, nothing dropped for room.
TEST(MapperSim, UscBlockWithAFarReachingWindowLetsItsOuterTilesLeaveEarly) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the pool fills over the whole path, which the optimized tree drives (the "
                  "memory tier lets tiles leave early in every tree)";
#endif
  const MapperRun run = map_with_far_reach("usc_block");
  expect_planes_issue_accuracy(run, score(run, "usc_block, true poses, far-reaching window"), 0.95);
  EXPECT_GT(run.tiles_left_early, 0u);
  EXPECT_EQ(run.points_dropped_full, 0u);
}

// config/far_reach_rtk.toml: with an RTK receiver the filter's poses find benning's far walls
// too when the scans are drawn 5 s late, with the smoothed path, whose heading is twice as
// good as the live one (docs/mapper.md, Accuracy; bench_accuracy's BM_BenningReach).
TEST(MapperSim, BenningWithAnRtkReceiverAndAFarReachingWindowMeetsThePlanesIssue) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive benning through the mapper";
#endif
  const map::VoxelWindowConfig window = far_reaching_window();
  const MapperRun run = map_world({.world = "benning",
                                   .robot = "paper_rmp_rtk",
                                   .pose_lag_s = 5.0,
                                   .window = &window,
                                   .max_range_m = kFarReachRangeM});
  expect_planes_issue_accuracy(run, score(run, "benning, RTK receiver, far-reaching window"), 0.95);
  EXPECT_EQ(run.points_dropped_full, 0u);
}

// Scans drawn 30 s late, with the smoothed path (LocalizerConfig::map_pose_lag_s): the loop's
// walls keep their directions. Measured on the whole path (filter seed 1): the best turn onto
// the truth is 0.17 deg (5.2 deg drawn live), 10 structural planes (18 live). Where the map
// sits stays the GPS's: 0.3-0.5 m across, 2.3 m in height.
TEST(MapperSim, UscBlockWithLaggedFilterPoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the lagged poses";
#endif
  const MapperRun run = map_world({.world = "usc_block", .pose_lag_s = 30.0});
  const testing::PlaneScore s = score(run, "usc_block, lagged filter poses");
  const AlignedScore a = score_aligned(run, "usc_block, lagged filter poses, aligned");
  // Over the filter's seeds 1-4 (2026-11-24): turns of 0.12-0.92 deg (2.4-5.7 deg live), 2-4
  // faces found after the turn, IoU 0.90-0.96. (One seed's 5/5 faces was a lucky draw.)
  EXPECT_LT(std::abs(a.alignment.yaw_rad) * 180.0 / std::numbers::pi, 1.5);
  EXPECT_GE(a.score.faces_found, 2u);
  EXPECT_LE(s.structural_planes, 15u);
  EXPECT_EQ(run.counters.scans_refused_full, 0u);
  EXPECT_LE(run.counters.scans_without_pose, 40u);  // before the first fix, as when live
  EXPECT_GT(run.counters.scans_projected, 20000u);
  expect_stream_gives_final_list(run);
  // The block's building: IoU 0.96 with seed 1 (0.91 drawn live).
  const std::vector<BuildingMatch> matches =
      building_matches(run, hal::sim::load_world("usc_block"), "usc_block, lagged");
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].shape, "rect");
  EXPECT_GE(matches[0].iou, 0.87);
}

TEST(MapperSim, UscBlockWithFilterPoses) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the optimized host trees drive usc_block with the filter's poses";
#endif
  const MapperRun run = map_world({.world = "usc_block"});
  const testing::PlaneScore s = score(run, "usc_block, filter poses");
  EXPECT_LE(s.structural_planes, 30u);
  const AlignedScore a = score_aligned(run, "usc_block, filter poses, aligned");
  EXPECT_GE(a.alignment.pairs, 3u);  // 3-5 pairs over the filter's seeds 1-4
  EXPECT_LT(a.alignment.shift_m.norm(), 5.0) << "a GPS-grade map is metres off at most";
  EXPECT_GE(a.score.structural_real, s.structural_real) << "aligned, no fewer planes lie on faces";
  expect_stream_gives_final_list(run);
  EXPECT_GT(run.counters.scans_projected, 20000u);
  // The level laser's scans matched (localize::ScanMatcher, on by default): the loop's walls
  // hold their directions. Seed 3 (2026-12-01): the best turn onto the truth 2.3 deg (5.2
  // unmatched), the block's rectangle IoU 0.927 (0.891); over seeds 1-4, 0.85-0.95 against
  // 0.81-0.91 (docs/localize.md, Scan matching).
  EXPECT_GT(run.scan_matched, run.scan_matcher_scans * 8 / 10);
  EXPECT_LT(std::abs(a.alignment.yaw_rad) * 180.0 / std::numbers::pi, 3.5);
  const std::vector<BuildingMatch> matches =
      building_matches(run, hal::sim::load_world("usc_block"), "usc_block, filter poses");
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].shape, "rect");
  EXPECT_GE(matches[0].iou, 0.91);
}

}  // namespace
}  // namespace blockmap::pipeline
