// Monte Carlo localization against a prior 2D map (localize::PriorMap, localize::MapLocalizer;
// docs/localize.md, A prior map): the likelihood field's distances and their direction, and
// the street of tests/support/synthetic_street.hpp driven with drifting odometry while the
// map places the robot.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/localize/map_localizer.hpp"
#include "blockmap/localize/prior_map.hpp"
#include "blockmap/localize/scan_matcher.hpp"
#include "synthetic_street.hpp"

namespace blockmap::localize {
namespace {

PriorMapConfig enabled_config() {
  PriorMapConfig config;
  config.enabled = true;
  return config;
}

TEST(PriorMap, HoldsTheDistanceToTheNearestWallAndWhichWayItGrows) {
  const PriorMapConfig config = enabled_config();
  Arena arena(PriorMap::arena_bytes(config));
  PriorMap map;
  map.init(arena, config);
  const std::vector<MapWall> walls = {{{0.0, 0.0}, {10.0, 0.0}}, {{10.0, 0.0}, {10.0, 6.0}}};
  ASSERT_EQ(map.build(walls), "");
  struct Expected {
    Eigen::Vector2d point_m;
    double distance_m;
    Eigen::Vector2d normal;
  };
  const Expected cases[] = {
      {{4.0, 0.3}, 0.3, {0.0, 1.0}},     // north of the first wall
      {{4.0, -0.35}, 0.35, {0.0, 1.0}},  // south of it
      {{4.0, 0.0}, 0.0, {0.0, 1.0}},     // on it, between two rows of cells
      {{10.3, 3.0}, 0.3, {1.0, 0.0}},    // east of the second
      {{10.0, 4.1}, 0.0, {1.0, 0.0}},    // on it
  };
  for (const Expected& expected : cases) {
    // Between cell centres the distance is interpolated: within half a cell on a wall.
    EXPECT_NEAR(map.distance_m(expected.point_m), expected.distance_m, config.cell_m / 2)
        << expected.point_m.transpose();
    const Eigen::Matrix2d outer = expected.normal * expected.normal.transpose();
    EXPECT_LT((map.normal_outer(expected.point_m) - outer).norm(), 0.15)
        << expected.point_m.transpose() << "\n"
        << map.normal_outer(expected.point_m);
  }
  // Beyond a wall's end, its nearest point is the end: a distance from a point, pinned in no
  // one direction.
  EXPECT_NEAR(map.distance_m({4.0, -2.5}), 2.5, PriorMap::kStepM);
  const Eigen::Matrix2d beyond_end = map.normal_outer({-0.5, 0.1});
  EXPECT_NEAR(beyond_end(0, 0), 0.5, 0.15) << beyond_end;
  EXPECT_NEAR(beyond_end(1, 1), 0.5, 0.15) << beyond_end;
  // Off the grid (the walls' extent and its margin): as far as it keeps.
  EXPECT_DOUBLE_EQ(map.distance_m({100.0, 100.0}), PriorMap::kMaxDistanceM);
}

TEST(PriorMap, RefusesAMapItCannotHold) {
  PriorMapConfig config = enabled_config();
  config.max_cells = 1000;
  Arena arena(PriorMap::arena_bytes(config));
  PriorMap map;
  map.init(arena, config);
  EXPECT_EQ(map.build({}), "the prior map has no walls");
  const std::vector<MapWall> wide = {{{0.0, 0.0}, {500.0, 0.0}}};
  EXPECT_NE(map.build(wide).find("over prior_map.max_cells (1000)"), std::string::npos)
      << map.build(wide);
  const std::vector<MapWall> broken = {{{0.0, 0.0}, {NAN, 0.0}}};
  EXPECT_NE(map.build(broken).find("not finite"), std::string::npos);
  EXPECT_FALSE(map.built());
}

TEST(PriorMap, KnowsWhatAFootprintEncloses) {
  const PriorMapConfig config = enabled_config();
  Arena arena(PriorMap::arena_bytes(config));
  PriorMap map;
  map.init(arena, config);
  // A closed 10 x 6 m footprint and, apart, a wall alone (a line: it encloses nothing).
  const Eigen::Vector2d corners[] = {{0.0, 0.0}, {10.0, 0.0}, {10.0, 6.0}, {0.0, 6.0}};
  std::vector<MapWall> walls;
  for (std::size_t k = 0; k < 4; ++k) {
    walls.push_back({corners[k], corners[(k + 1) % 4], true});
  }
  walls.push_back({{20.0, 0.0}, {20.0, 6.0}, false});
  ASSERT_EQ(map.build(walls), "");
  EXPECT_TRUE(map.inside({5.0, 3.0}));
  EXPECT_TRUE(map.inside({0.5, 5.5}));
  EXPECT_FALSE(map.inside({-0.5, 3.0}));
  EXPECT_FALSE(map.inside({5.0, 6.5}));
  EXPECT_FALSE(map.inside({15.0, 3.0}));
  EXPECT_FALSE(map.inside({21.0, 3.0}));
}

// The street driven out and back. The path's own frame (what the scan matcher gives) is
// turned by 30 degrees and moved from the local one, and its motion drifts: 1 % too long and
// turning 0.004 degrees a metre too far (a degree over the drive). The map holds the
// facades as lines.
struct StreetRun {
  std::vector<MapPlacing> placings;
  std::vector<Pose2> truths;  // at each placing
  MapLocalizerCounters counters;
  std::size_t memory_bytes = 0;
};

StreetRun drive_the_street(const PriorMapConfig& config) {
  const std::vector<synthetic_street::Facade> facades = synthetic_street::street_of(8.0);
  const std::vector<MapWall> walls = synthetic_street::map_walls_of(facades);
  Arena arena(MapLocalizer::arena_bytes(config));
  MapLocalizer localizer;
  localizer.init(arena, config);
  EXPECT_EQ(localizer.set_map(walls), "");
  StreetRun run;
  const Pose2 start = synthetic_street::street_truth_at(0.0);
  Pose2 path{start.stamp_ns, -40.0, 25.0, radians_from_degrees(30.0)};
  localizer.start(start, path, 0.05, radians_from_degrees(0.3));
  Pose2 last_truth = start;
  for (double s_m = 0.5; s_m <= 2.0 * synthetic_street::kStreetM; s_m += 0.5) {
    const Pose2 truth = synthetic_street::street_truth_at(s_m);
    const Eigen::Vector3d moved = pose_in_frame_of(last_truth, truth);
    const double ahead_m = 1.01 * moved.x();
    const double left_m = 1.01 * moved.y();
    path.x_m += std::cos(path.yaw_rad) * ahead_m - std::sin(path.yaw_rad) * left_m;
    path.y_m += std::sin(path.yaw_rad) * ahead_m + std::cos(path.yaw_rad) * left_m;
    path.yaw_rad += moved.z() + radians_from_degrees(0.004) * std::hypot(ahead_m, left_m);
    path.stamp_ns = truth.stamp_ns;
    last_truth = truth;
    MapPlacing placing;
    if (localizer.add_scan(path, synthetic_street::laser_scan_at(facades, truth), placing)) {
      run.placings.push_back(placing);
      run.truths.push_back(truth);
    }
  }
  run.counters = localizer.counters();
  run.memory_bytes = localizer.memory_bytes();
  return run;
}

TEST(MapLocalizer, PlacesTheRobotOnTheMapWhereverThePathsFrameIs) {
  const PriorMapConfig config = enabled_config();
  const StreetRun run = drive_the_street(config);
  // A placing every 2 m of the 280 m, but where the particles had not yet settled.
  ASSERT_GT(run.placings.size(), 100U) << run.counters.updates << " updates";
  std::size_t outside_three_sigmas = 0;
  double worst_across_m = 0.0;
  for (std::size_t k = 0; k < run.placings.size(); ++k) {
    const MapPlacing& placing = run.placings[k];
    const Eigen::Vector2d error(placing.pose.x_m - run.truths[k].x_m,
                                placing.pose.y_m - run.truths[k].y_m);
    outside_three_sigmas += error.dot(placing.information * error) > 9.0 ? 1U : 0U;
    worst_across_m = std::max(worst_across_m, std::abs(error.y()));
    // The facades pin the position across the street, to 0.3 m a placing at the least.
    EXPECT_GT(placing.information(1, 1), 10.0) << k;
    EXPECT_LT(std::abs(wrap_angle(placing.pose.yaw_rad - run.truths[k].yaw_rad)),
              radians_from_degrees(0.5))
        << k;
  }
  EXPECT_LT(worst_across_m, 0.1);
  EXPECT_LE(outside_three_sigmas, run.placings.size() / 20) << "of " << run.placings.size();
  EXPECT_LE(run.memory_bytes, MapLocalizer::arena_bytes(config));
}

TEST(MapLocalizer, SaysNothingAlongABareStreet) {
  // One long facade and nothing across it: the placings pin the position across the wall
  // only, whatever the particles guess along it.
  const PriorMapConfig config = enabled_config();
  Arena arena(MapLocalizer::arena_bytes(config));
  MapLocalizer localizer;
  localizer.init(arena, config);
  const std::vector<MapWall> walls = {{{-50.0, 8.0}, {250.0, 8.0}}};
  ASSERT_EQ(localizer.set_map(walls), "");
  const std::vector<synthetic_street::Facade> facades = {{{-50.0, 8.0}, {250.0, 8.0}}};
  const Pose2 start = synthetic_street::street_truth_at(0.0);
  localizer.start(start, start, 0.05, radians_from_degrees(0.3));
  std::size_t placings = 0;
  for (double s_m = 0.0; s_m <= 100.0; s_m += 0.5) {
    const Pose2 truth = synthetic_street::street_truth_at(s_m);
    MapPlacing placing;
    if (localizer.add_scan(truth, synthetic_street::laser_scan_at(facades, truth), placing)) {
      ++placings;
      EXPECT_NEAR(placing.information(0, 0), 0.0, 1e-6);
      EXPECT_GT(placing.information(1, 1), 25.0);
      EXPECT_NEAR(placing.pose.y_m, truth.y_m, 0.1);
    }
  }
  EXPECT_GT(placings, 40U);
}

}  // namespace
}  // namespace blockmap::localize
