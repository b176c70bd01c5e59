// The batch detector's accuracy on the simulated worlds: the cloud every laser return makes along
// the true trajectory, scored against the world's truth faces.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <numbers>
#include <string>

#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"
#include "long_test.hpp"
#include "plane_truth.hpp"
#include "truth_cloud_runs.hpp"

namespace blockmap::planes {
namespace {

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

// Robustness: the world turned so that the ground slopes 3 deg and the walls lean
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

// Pose noise (0.5 deg / 5 cm, the project's target): every scan of every laser gets its own error,
// 0.5 deg about each axis and 5 cm along each, so a wall 15 m away is a slab about 0.13 m
// thick. usc_block and benning meet the issue's recall (benning's glimpsed east and west
// sides through the corner look); partial does not (docs/benchmarks.md has the table).
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

}  // namespace
}  // namespace blockmap::planes
