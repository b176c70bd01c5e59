// Scoring a map against a simulated run's truth (hal/sim/truth_score.hpp): the path laid onto
// the true one by the least-squares rigid motion, and footprints by their overlap.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>

#include "blockmap/hal/sim/truth_score.hpp"

namespace blockmap::hal::sim {
namespace {

// Round a 40 x 20 m block at 1 m/s, a position every 0.1 s.
std::vector<TimedPosition> block_loop() {
  const std::vector<Eigen::Vector2d> corners{{0, 0}, {40, 0}, {40, 20}, {0, 20}, {0, 0}};
  constexpr double kStepM = 0.1;
  std::vector<TimedPosition> path;
  double t_s = 100.0;
  for (std::size_t side = 0; side + 1 < corners.size(); ++side) {
    const Eigen::Vector2d& from = corners[side];
    const Eigen::Vector2d& to = corners[side + 1];
    const auto steps = static_cast<int>(std::lround((to - from).norm() / kStepM));
    for (int k = 0; k < steps; ++k) {
      const Eigen::Vector2d p = from + (to - from) * (static_cast<double>(k) / steps);
      path.push_back({t_s, Eigen::Vector3d(p.x(), p.y(), 0.3)});
      t_s += kStepM;
    }
  }
  return path;
}

TEST(AlignPath, AnEstimateTurnedAndShiftedIsLaidBackOntoTheTruth) {
  const std::vector<TimedPosition> truth = block_loop();
  // The estimate: the truth turned 3 deg about the origin, shifted 2 m east, 1 m south and
  // 0.5 m up, every other sample only (its own times).
  const Eigen::AngleAxisd turn(3.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ());
  std::vector<TimedPosition> estimate;
  for (std::size_t i = 0; i < truth.size(); i += 2) {
    estimate.push_back({truth[i].t_s, turn * truth[i].position_m + Eigen::Vector3d(2, -1, 0.5)});
  }
  const PathAlignment alignment = align_path(estimate, truth);
  EXPECT_EQ(alignment.pairs, estimate.size());
  EXPECT_NEAR(alignment.yaw_rad, -3.0 * std::numbers::pi / 180.0, 1e-9);
  EXPECT_NEAR(alignment.shift_m.z(), -0.5, 1e-9);
  // Where it sits: its centroid, turned 3 deg about the origin and shifted, less the truth's.
  Eigen::Vector3d true_centroid_m = Eigen::Vector3d::Zero();
  for (const TimedPosition& pose : estimate) {
    true_centroid_m += turn.inverse() * (pose.position_m - Eigen::Vector3d(2, -1, 0.5)) /
                       static_cast<double>(estimate.size());
  }
  const Eigen::Vector3d offset_m =
      turn * true_centroid_m + Eigen::Vector3d(2, -1, 0.5) - true_centroid_m;
  EXPECT_LT((alignment.offset_m - offset_m.head<2>()).norm(), 1e-9);
  EXPECT_LT(alignment.rms_m, 1e-9);
  EXPECT_LT(alignment.max_m, 1e-9);
  for (const TimedPosition& pose : estimate) {
    EXPECT_LT((alignment.apply(pose.position_m) -
               (turn.inverse() * (pose.position_m - Eigen::Vector3d(2, -1, 0.5))))
                  .norm(),
              1e-9);
  }
}

TEST(AlignPath, WhatIsLeftAfterTheMotionIsThePathsOwnShape) {
  const std::vector<TimedPosition> truth = block_loop();
  // A path bent at its far end: the east side drawn 0.4 m further east.
  std::vector<TimedPosition> estimate = truth;
  for (TimedPosition& pose : estimate) {
    if (pose.position_m.x() > 39.9) {
      pose.position_m.x() += 0.4;
    }
  }
  const PathAlignment alignment = align_path(estimate, truth);
  EXPECT_GT(alignment.max_m, 0.2);
  EXPECT_LT(alignment.max_m, 0.4);
  EXPECT_GT(alignment.median_m, 0.0);
  EXPECT_LT(alignment.rms_m, alignment.max_m);
}

TEST(AlignPath, PosesOutsideTheTruthsSpanAreLeftOutAndTimesInterpolated) {
  const std::vector<TimedPosition> truth = block_loop();
  std::vector<TimedPosition> estimate{{truth.front().t_s - 1.0, Eigen::Vector3d(9, 9, 9)},
                                      {truth.back().t_s + 1.0, Eigen::Vector3d(9, 9, 9)}};
  // Half way between two true samples 0.1 m apart along x.
  for (std::size_t i = 0; i + 1 < 50; ++i) {
    estimate.push_back({0.5 * (truth[i].t_s + truth[i + 1].t_s),
                        0.5 * (truth[i].position_m + truth[i + 1].position_m)});
  }
  const PathAlignment alignment = align_path(estimate, truth);
  EXPECT_EQ(alignment.pairs, 49u);
  EXPECT_LT(alignment.rms_m, 1e-9);
  EXPECT_EQ(align_path({}, truth).pairs, 0u);
}

TEST(FootprintIou, SquaresOverlappingByHalfScoreAThird) {
  const std::vector<Eigen::Vector2d> a{{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  const std::vector<Eigen::Vector2d> b{{5, 0}, {15, 0}, {15, 10}, {5, 10}};
  EXPECT_NEAR(footprint_iou(a, b), 1.0 / 3.0, 0.01);
  EXPECT_NEAR(footprint_iou(a, a), 1.0, 1e-9);
  EXPECT_EQ(footprint_iou(a, std::vector<Eigen::Vector2d>{{0, 0}, {1, 1}}), 0.0);
}

}  // namespace
}  // namespace blockmap::hal::sim
