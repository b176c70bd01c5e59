// The scan matcher on a synthetic street: a level laser's scans ray-cast against walls and
// posts at known poses, drawn with odometry that drifts, matched back onto the walls.
#include "blockmap/localize/scan_matcher.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "long_test.hpp"
#include "own_arena.hpp"

namespace blockmap::localize {
namespace {

constexpr double kDegree = std::numbers::pi / 180.0;
constexpr TimestampNs kScanPeriodNs = 13'333'333;  // 75 Hz

struct Segment {
  Eigen::Vector2d from_m;
  Eigen::Vector2d to_m;
};

// A street 12 m wide between two facades with doorways, crossed by a side street, with a
// few posts: along the street the facades alone say nothing, the posts and ends do.
std::vector<Segment> street() {
  std::vector<Segment> scene;
  for (double x = -20.0; x < 60.0; x += 8.0) {
    scene.push_back({{x, 6.0}, {x + 6.5, 6.0}});        // north facade, a doorway every 8 m
    scene.push_back({{x + 6.5, 6.0}, {x + 6.5, 7.0}});  // the doorway's jamb
    if (x < 20.0 || x > 28.0) {
      scene.push_back({{x, -6.0}, {x + 7.0, -6.0}});  // south facade, the side street at 20-28 m
    }
  }
  scene.push_back({{20.0, -6.0}, {20.0, -20.0}});
  scene.push_back({{28.0, -6.0}, {28.0, -20.0}});
  for (double x = -15.0; x < 60.0; x += 11.0) {  // posts 0.3 m square
    const Eigen::Vector2d c(x, -4.5);
    scene.push_back({c + Eigen::Vector2d(-0.15, -0.15), c + Eigen::Vector2d(0.15, -0.15)});
    scene.push_back({c + Eigen::Vector2d(0.15, -0.15), c + Eigen::Vector2d(0.15, 0.15)});
    scene.push_back({c + Eigen::Vector2d(0.15, 0.15), c + Eigen::Vector2d(-0.15, 0.15)});
    scene.push_back({c + Eigen::Vector2d(-0.15, 0.15), c + Eigen::Vector2d(-0.15, -0.15)});
  }
  return scene;
}

std::optional<double> ray_hit(const std::vector<Segment>& scene, const Eigen::Vector2d& origin,
                              const Eigen::Vector2d& direction, double max_range_m) {
  std::optional<double> best;
  for (const Segment& segment : scene) {
    const Eigen::Vector2d edge = segment.to_m - segment.from_m;
    const double denominator = direction.x() * edge.y() - direction.y() * edge.x();
    if (std::abs(denominator) < 1e-12) {
      continue;
    }
    const Eigen::Vector2d offset = segment.from_m - origin;
    const double range = (offset.x() * edge.y() - offset.y() * edge.x()) / denominator;
    const double along = (offset.x() * direction.y() - offset.y() * direction.x()) / denominator;
    if (range > 0.1 && range < max_range_m && along >= 0.0 && along <= 1.0 &&
        (!best || range < *best)) {
      best = range;
    }
  }
  return best;
}

// A 180-degree scan at 1 degree from `truth` (robot frame: x forward), its points drawn with
// `drawn` instead (where the filter thinks the robot is), at `height_m`.
std::vector<Eigen::Vector3f> scan_drawn_at(const std::vector<Segment>& scene, const Pose2& truth,
                                           const Pose2& drawn, double height_m) {
  std::vector<Eigen::Vector3f> points;
  for (int beam = 0; beam <= 180; ++beam) {
    const double bearing = (beam - 90) * kDegree;
    const Eigen::Vector2d direction(std::cos(truth.yaw_rad + bearing),
                                    std::sin(truth.yaw_rad + bearing));
    const std::optional<double> range =
        ray_hit(scene, Eigen::Vector2d(truth.x_m, truth.y_m), direction, 40.0);
    if (!range) {
      continue;
    }
    const Eigen::Vector2d local(*range * std::cos(bearing), *range * std::sin(bearing));
    const double c = std::cos(drawn.yaw_rad);
    const double s = std::sin(drawn.yaw_rad);
    points.emplace_back(static_cast<float>(drawn.x_m + c * local.x() - s * local.y()),
                        static_cast<float>(drawn.y_m + s * local.x() + c * local.y()),
                        static_cast<float>(height_m));
  }
  return points;
}

// The robot drives east along the street at 1.2 m/s, weaving a little.
Pose2 truth_at(int scan) {
  const double t = static_cast<double>(scan) * static_cast<double>(kScanPeriodNs) * 1e-9;
  Pose2 pose;
  pose.stamp_ns = static_cast<TimestampNs>(scan) * kScanPeriodNs;
  pose.x_m = -10.0 + 1.2 * t;
  pose.y_m = 0.8 * std::sin(0.2 * t);
  pose.yaw_rad = std::atan2(0.16 * std::cos(0.2 * t), 1.2);
  return pose;
}

// Dead reckoning that reads 3 % too far and turns 0.4 deg/s too much: metres off in a minute.
Pose2 odometry_at(int scan) {
  Pose2 odometry = truth_at(0);
  for (int k = 1; k <= scan; ++k) {
    const Pose2 a = truth_at(k - 1);
    const Pose2 b = truth_at(k);
    const double c = std::cos(a.yaw_rad);
    const double s = std::sin(a.yaw_rad);
    const double forward = 1.03 * (c * (b.x_m - a.x_m) + s * (b.y_m - a.y_m));
    const double turn = std::remainder(b.yaw_rad - a.yaw_rad, 2.0 * std::numbers::pi) +
                        0.4 * kDegree * static_cast<double>(kScanPeriodNs) * 1e-9;
    odometry.x_m += forward * std::cos(odometry.yaw_rad + 0.5 * turn);
    odometry.y_m += forward * std::sin(odometry.yaw_rad + 0.5 * turn);
    odometry.yaw_rad += turn;
  }
  odometry.stamp_ns = truth_at(scan).stamp_ns;
  return odometry;
}

ScanMatchConfig street_config() {
  ScanMatchConfig config;
  config.enabled = true;
  config.cells_across = 1024;
  config.anchor_time_s = 0.0;  // the matcher's frame stays the first scan's
  return config;
}

using OwnArena = testing::OnOwnArena<ScanMatcher>;

TEST(ScanMatcher, MatchedPosesFollowTheStreetWhereTheOdometryDrifts) {
  BLOCKMAP_LONG_TEST();
  const std::vector<Segment> scene = street();
  const ScanMatchConfig config = street_config();
  OwnArena sealed(config);
  ScanMatcher& matcher = sealed.part;
  // The street runs east (x): across it is y. The odometry's distance is believed along the
  // way (ScanMatchConfig::prior_along_ratio), so along it the matched pose keeps most of the
  // odometry's 3 %; across it and in heading, where a wrong pose bends the walls, the grid
  // holds it.
  double worst_across_m = 0.0;
  double worst_heading_rad = 0.0;
  double worst_along_m = 0.0;
  double odometry_across_m = 0.0;
  double odometry_heading_rad = 0.0;
  double odometry_along_m = 0.0;
  constexpr int kScans = 75 * 40;  // 40 s, 48 m of street
  for (int scan = 0; scan < kScans; ++scan) {
    const Pose2 truth = truth_at(scan);
    const Pose2 odometry = odometry_at(scan);
    // The filter's pose is the odometry here: no GPS to pull it back.
    const std::vector<Eigen::Vector3f> points = scan_drawn_at(scene, truth, odometry, 0.8);
    const Pose2 corrected = matcher.add_scan(odometry, odometry, 0.0, points).apply(odometry);
    const auto heading_off = [&truth](const Pose2& pose) {
      return std::abs(std::remainder(pose.yaw_rad - truth.yaw_rad, 2.0 * std::numbers::pi));
    };
    worst_across_m = std::max(worst_across_m, std::abs(corrected.y_m - truth.y_m));
    worst_along_m = std::max(worst_along_m, std::abs(corrected.x_m - truth.x_m));
    worst_heading_rad = std::max(worst_heading_rad, heading_off(corrected));
    odometry_across_m = std::max(odometry_across_m, std::abs(odometry.y_m - truth.y_m));
    odometry_along_m = std::max(odometry_along_m, std::abs(odometry.x_m - truth.x_m));
    odometry_heading_rad = std::max(odometry_heading_rad, heading_off(odometry));
  }
  std::printf(
      "odometry up to %.2f m across, %.2f m along and %.1f deg off; matched %.3f m, %.2f m "
      "and %.3f deg\n",
      odometry_across_m, odometry_along_m, odometry_heading_rad / kDegree, worst_across_m,
      worst_along_m, worst_heading_rad / kDegree);
  EXPECT_GT(odometry_across_m, 3.0);
  EXPECT_GT(odometry_heading_rad, 10.0 * kDegree);
  EXPECT_LT(worst_across_m, 0.1);  // half a cell: the facades lie on the grid's cell edges
  EXPECT_LT(worst_heading_rad, 0.2 * kDegree);
  EXPECT_LT(worst_along_m, 0.035 * 48.0);  // the odometry's 3 % of the way, no more
  EXPECT_GT(matcher.counters().matched, static_cast<std::uint64_t>(kScans) * 9 / 10);
  EXPECT_EQ(matcher.counters().too_far, 0u);
}

// The heading error after 30 s of street matched and 10 s with no scan to match (an open
// square): the odometry's turn alone carries the pose through, with the bias the matcher
// learnt (bias_time_s > 0) or as it comes (0).
double heading_after_an_outage_rad(double bias_time_s, double& learnt_radps) {
  const std::vector<Segment> scene = street();
  ScanMatchConfig config = street_config();
  config.yaw_rate_bias_time_s = bias_time_s;
  OwnArena sealed(config);
  ScanMatcher& matcher = sealed.part;
  constexpr int kMatchedScans = 75 * 30;
  constexpr int kScans = 75 * 40;
  Pose2 corrected;
  for (int scan = 0; scan < kScans; ++scan) {
    const Pose2 odometry = odometry_at(scan);
    const std::vector<Eigen::Vector3f> points =
        scan < kMatchedScans ? scan_drawn_at(scene, truth_at(scan), odometry, 0.8)
                             : std::vector<Eigen::Vector3f>{};
    corrected = matcher.add_scan(odometry, odometry, 0.0, points).apply(odometry);
  }
  learnt_radps = matcher.yaw_rate_bias_radps();
  return std::abs(
      std::remainder(corrected.yaw_rad - truth_at(kScans - 1).yaw_rad, 2.0 * std::numbers::pi));
}

TEST(ScanMatcher, LearnsTheGyroscopeBiasFromItsMatches) {
  BLOCKMAP_LONG_TEST();
  // The odometry turns 0.4 deg/s too much. Matched, each scan's turn from its prediction says
  // so; the bias learnt carries the heading through the outage, where the odometry's turn as
  // it comes is 4 deg off.
  double learnt_radps = 0.0;
  const double learning = heading_after_an_outage_rad(20.0, learnt_radps);
  EXPECT_NEAR(learnt_radps, 0.4 * kDegree, 0.1 * kDegree);
  EXPECT_LT(learning, 1.0 * kDegree);
  double unused_radps = 0.0;
  const double as_it_comes = heading_after_an_outage_rad(0.0, unused_radps);
  EXPECT_EQ(unused_radps, 0.0);
  EXPECT_GT(as_it_comes, 3.5 * kDegree);
  std::printf(
      "heading after 10 s without scans: %.2f deg with the bias learnt (%.3f deg/s), "
      "%.2f deg without\n",
      learning / kDegree, learnt_radps / kDegree, as_it_comes / kDegree);
}

TEST(ScanMatcher, TheAnchorLaysTheMatchedPathOntoTheFiltersPath) {
  // The first scan's pose is 8 deg and 1 m off (the filter before its heading settles), the
  // filter's poses after it are right: the matcher's frame keeps the first scan's error, and
  // the anchor takes it out as the path grows.
  const std::vector<Segment> scene = street();
  ScanMatchConfig config = street_config();
  config.anchor_time_s = 1e6;  // every sample counts alike
  OwnArena sealed(config);
  ScanMatcher& matcher = sealed.part;
  constexpr int kScans = 75 * 30;
  Pose2 corrected;
  Pose2 truth;
  for (int scan = 0; scan < kScans; ++scan) {
    truth = truth_at(scan);
    Pose2 filter = truth;
    if (scan == 0) {
      filter.x_m += 1.0;
      filter.yaw_rad += 8.0 * kDegree;
    }
    const std::vector<Eigen::Vector3f> points = scan_drawn_at(scene, truth, filter, 0.8);
    corrected = matcher.add_scan(filter, truth, 0.0, points).apply(filter);
  }
  // The matcher's own frame is still the first scan's.
  EXPECT_NEAR(std::remainder(matcher.matched().yaw_rad - truth.yaw_rad, 2.0 * std::numbers::pi),
              8.0 * kDegree, 0.5 * kDegree);
  EXPECT_LT(std::hypot(corrected.x_m - truth.x_m, corrected.y_m - truth.y_m), 0.1);
  EXPECT_LT(std::abs(std::remainder(corrected.yaw_rad - truth.yaw_rad, 2.0 * std::numbers::pi)),
            0.1 * kDegree);
}

TEST(ScanMatcher, RefusesWhatItCannotMatchAndForgetsWhatLeftTheGrid) {
  ScanMatchConfig config = street_config();
  config.cells_across = 128;  // 12.8 m
  config.levels = 3;
  OwnArena sealed(config);
  ScanMatcher& matcher = sealed.part;
  const std::vector<Segment> scene = street();
  const Pose2 here = truth_at(0);
  const std::vector<Eigen::Vector3f> points = scan_drawn_at(scene, here, here, 0.8);
  ASSERT_GT(points.size(), 100u);
  (void)matcher.add_scan(here, here, 0.0, points);  // the first scan only makes the map
  EXPECT_EQ(matcher.counters().off_map, 1u);
  Eigen::Vector2d wall_m(points[0].x(), points[0].y());
  for (const Eigen::Vector3f& point : points) {  // the nearest return: inside the small grid
    const Eigen::Vector2d at_m(point.x(), point.y());
    if ((at_m - Eigen::Vector2d(here.x_m, here.y_m)).norm() <
        (wall_m - Eigen::Vector2d(here.x_m, here.y_m)).norm()) {
      wall_m = at_m;
    }
  }
  EXPECT_GT(matcher.hits_at(wall_m), 0);
  // Returns outside the height band (the ground a pitching laser meets) are not landmarks.
  const std::vector<Eigen::Vector3f> ground = scan_drawn_at(scene, here, here, -0.5);
  Pose2 next = here;
  next.stamp_ns += kScanPeriodNs;
  (void)matcher.add_scan(next, next, 0.0, ground);
  EXPECT_EQ(matcher.counters().few_points, 1u);
  // 30 m on, the grid has scrolled past where it was: the wall's cell is forgotten.
  Pose2 far = here;
  far.x_m += 30.0;
  far.stamp_ns += 2 * kScanPeriodNs;
  (void)matcher.add_scan(far, far, 0.0, scan_drawn_at(scene, far, far, 0.8));
  EXPECT_EQ(matcher.hits_at(wall_m), 0);
  // A scan 1 m and 5 deg from where it was seen a moment ago steps further than a scan can.
  Pose2 jumped = far;
  jumped.stamp_ns += kScanPeriodNs;
  Pose2 seen = jumped;
  seen.x_m += 0.25;
  seen.yaw_rad += 5.0 * kDegree;
  (void)matcher.add_scan(jumped, jumped, 0.0, scan_drawn_at(scene, seen, jumped, 0.8));
  EXPECT_EQ(matcher.counters().too_far + matcher.counters().off_map, 3u);
  EXPECT_EQ(matcher.counters().matched, 0u);
  // The filter's poses jumped: the grid starts over, and the correction with it.
  matcher.reset();
  EXPECT_TRUE(matcher.correction().identity());
  EXPECT_EQ(matcher.counters().resets, 1u);
}

// The grid keeps what the robot saw lately: a cell no scan has hit over forget_after_m of
// travel is cleared, so that a street seen long ago (on another pass, with another drift)
// does not pull the pose; what the scans still hit stays.
TEST(ScanMatcher, ForgetsWhatNoScanHasHitForAWhile) {
  const std::vector<Segment> scene = street();
  const auto drive = [&scene](double forget_after_m, Eigen::Vector2d& first_hit_m,
                              Eigen::Vector2d& last_hit_m) {
    ScanMatchConfig config = street_config();
    config.forget_after_m = forget_after_m;
    OwnArena sealed(config);
    ScanMatcher& matcher = sealed.part;
    constexpr int kScans = 600;  // 9.6 m east
    for (int scan = 0; scan <= kScans; ++scan) {
      const Pose2 truth = truth_at(scan);
      const std::vector<Eigen::Vector3f> points = scan_drawn_at(scene, truth, truth, 0.8);
      (void)matcher.add_scan(truth, truth, 0.0, points);
      // The return straight to the left: the north facade beside the robot.
      const Eigen::Vector3f& left = points[points.size() - 1];
      (scan == 0 ? first_hit_m : last_hit_m) = Eigen::Vector2d(left.x(), left.y());
    }
    EXPECT_GT(matcher.counters().matched, std::uint64_t{kScans} * 9 / 10);
    return std::pair<int, int>(matcher.hits_at(first_hit_m), matcher.hits_at(last_hit_m));
  };
  Eigen::Vector2d first_hit_m;
  Eigen::Vector2d last_hit_m;
  const auto [first_kept, last_kept] = drive(0.0, first_hit_m, last_hit_m);
  EXPECT_GT(first_kept, 0) << "never forgetting, the grid holds the start";
  EXPECT_GT(last_kept, 0);
  ASSERT_GT((last_hit_m - first_hit_m).norm(), 9.0);
  const auto [first_forgotten, last_still] = drive(4.0, first_hit_m, last_hit_m);
  EXPECT_EQ(first_forgotten, 0) << "9.6 m on, the facade beside the start is forgotten";
  EXPECT_GT(last_still, 0) << "what the last scans hit is kept";
}

TEST(ScanMatcher, AnUnusableConfigurationIsNamed) {
  ScanMatchConfig config = street_config();
  EXPECT_EQ(validate(config), "");
  config.cells_across = 1000;
  EXPECT_NE(validate(config).find("power of two"), std::string::npos);
  config = street_config();
  config.levels = 8;
  EXPECT_NE(validate(config).find("levels"), std::string::npos);
  config = street_config();
  config.min_points = 600;
  EXPECT_NE(validate(config).find("min_points"), std::string::npos);
  config = street_config();
  config.max_height_m = config.min_height_m;
  EXPECT_NE(validate(config).find("min_height_m"), std::string::npos);
  config = street_config();
  config.forget_after_m = -1.0;
  EXPECT_NE(validate(config).find("forget_after_m"), std::string::npos);
  config.enabled = false;
  EXPECT_EQ(validate(config), "") << "a matcher that is off is not checked";
}

}  // namespace
}  // namespace blockmap::localize
