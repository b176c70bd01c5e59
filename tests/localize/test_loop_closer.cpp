// Loop closing (localize::LoopCloser) on a street with buildings on both sides and gaps
// between them: out along it and back on the other side of the road, the way back's
// odometry turned by a degree and shifted by half a metre (the drift of a few hundred metres
// of matched scans). Each finished submap of the way back is matched against the way out's,
// and the closure must say where the two poses truly lie to each other (docs/localize.md,
// Loop closing).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/localize/loop_closer.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "long_test.hpp"
#include "synthetic_street.hpp"

namespace blockmap::localize {
namespace {

using synthetic_street::drifted_back;
using synthetic_street::Facade;
using synthetic_street::kScanStepM;
using synthetic_street::kStreetM;
using synthetic_street::laser_scan_at;
using synthetic_street::street_of;
using synthetic_street::street_truth_at;

struct StreetDrive {
  std::vector<LoopClosure> closures;
  std::vector<Pose2> truths;  // the odometry -> truth of each pose added, by stamp
  LoopClosureCounters counters;
  std::size_t submaps = 0;
  std::size_t memory_bytes = 0;
};

// A loop closer and the path it reads, in one arena.
struct CloserAndPath {
  explicit CloserAndPath(const LoopClosureConfig& config)
      : arena(LoopCloser::arena_bytes(config) + PathSmoother::arena_bytes(PathSmootherConfig{})) {
    closer.init(arena, config);
    path.init(arena, PathSmootherConfig{});
  }
  Arena arena;
  LoopCloser closer;
  PathSmoother path;
};

// How the way back's odometry is off, and whether the path holds fixes (which fix the
// search window's size: the receiver bounds how far apart two passes are drawn).
struct WayBack {
  double turn_deg = 1.0;
  Eigen::Vector2d about_m = Eigen::Vector2d(kStreetM, 0.0);
  bool fixes = false;
};

// Drives out and back, the way back seeing `back_walls`, and collects every closure.
StreetDrive drive_out_and_back(const LoopClosureConfig& config,
                               const std::vector<Facade>& back_walls, const WayBack& back = {}) {
  const std::vector<Facade> out_walls = street_of(8.0);
  CloserAndPath run(config);
  LoopCloser& closer = run.closer;
  PathSmoother& path = run.path;
  StreetDrive closed;
  std::array<LoopClosure, kMaxClosureCandidates> found{};
  for (double s = 0.0; s <= 2.0 * kStreetM; s += kScanStepM) {
    const Pose2 truth = street_truth_at(s);
    const Pose2 odometry = drifted_back(truth, back.turn_deg, back.about_m);
    closed.truths.push_back(truth);
    path.add(odometry, back.fixes
                           ? std::optional<Eigen::Vector2d>(Eigen::Vector2d(truth.x_m, truth.y_m))
                           : std::nullopt);
    if (closer.add_scan(odometry, laser_scan_at(s <= kStreetM ? out_walls : back_walls, truth))) {
      const std::size_t count = closer.find_closures(path, found);
      closed.closures.insert(closed.closures.end(), found.begin(),
                             found.begin() + static_cast<std::ptrdiff_t>(count));
    }
  }
  closed.counters = closer.counters();
  closed.submaps = closer.submap_count();
  closed.memory_bytes = closer.memory_bytes();
  return closed;
}

Pose2 truth_at_stamp(const StreetDrive& closed, TimestampNs stamp_ns) {
  for (const Pose2& truth : closed.truths) {
    if (truth.stamp_ns == stamp_ns) {
      return truth;
    }
  }
  ADD_FAILURE() << "no pose at " << stamp_ns;
  return {};
}

TEST(LoopCloser, TheWayBackIsMatchedToTheWayOutWhereTheyTrulyLie) {
  const StreetDrive closed = drive_out_and_back(LoopClosureConfig{}, street_of(8.0));
  std::printf("%llu submaps, %llu matched against an earlier one, %zu closures\n",
              static_cast<unsigned long long>(closed.counters.submaps),
              static_cast<unsigned long long>(closed.counters.searches), closed.closures.size());
  ASSERT_GE(closed.closures.size(), 5u);
  double worst_m = 0.0;
  double worst_rad = 0.0;
  double worst_sigmas = 0.0;
  for (const LoopClosure& closure : closed.closures) {
    const Eigen::Vector3d truly = pose_in_frame_of(truth_at_stamp(closed, closure.earlier.stamp_ns),
                                                   truth_at_stamp(closed, closure.later.stamp_ns));
    const Eigen::Vector3d odometry = pose_in_frame_of(closure.earlier, closure.later);
    // The odometry is off by the drift: the closure is not.
    EXPECT_GT((odometry - truly).head<2>().norm(), 0.3);
    worst_m = std::max(worst_m, (closure.measured - truly).head<2>().norm());
    Eigen::Vector3d error = closure.measured - truly;
    error.z() = wrap_angle(error.z());
    worst_sigmas = std::max(worst_sigmas, std::sqrt(error.dot(closure.information * error)));
    worst_rad = std::max(worst_rad, std::abs(wrap_angle(closure.measured.z() - truly.z())));
    // Its information: positive definite.
    EXPECT_GT(closure.information.ldlt().vectorD().minCoeff(), 0.0);
  }
  std::printf("worst closure: %.3f m, %.3f deg off the truth; %.2f sigmas by its information\n",
              worst_m, degrees_from_radians(worst_rad), worst_sigmas);
  // Within the wall's tolerance, and where its information says it is sure, within it.
  EXPECT_LT(worst_m, 0.2);
  EXPECT_LT(worst_sigmas, 3.0);
  EXPECT_LT(degrees_from_radians(worst_rad), 0.2);
}

// The worst closure's offset from the truth, in metres and degrees.
Eigen::Vector2d worst_closure_error(const StreetDrive& closed) {
  Eigen::Vector2d worst = Eigen::Vector2d::Zero();
  for (const LoopClosure& closure : closed.closures) {
    const Eigen::Vector3d truly = pose_in_frame_of(truth_at_stamp(closed, closure.earlier.stamp_ns),
                                                   truth_at_stamp(closed, closure.later.stamp_ns));
    worst.x() = std::max(worst.x(), (closure.measured - truly).head<2>().norm());
    worst.y() = std::max(
        worst.y(), degrees_from_radians(std::abs(wrap_angle(closure.measured.z() - truly.z()))));
  }
  return worst;
}

TEST(LoopCloser, ARevisitTurnedPastTheWindowIsFoundByTheWiderSearch) {
  // With fixes the window is 2.5 m and 3 degrees; the way back turned 4 degrees (where the
  // gyroscope alone carried the newest stretch) is past it, and the wider search (4 m,
  // 5 degrees, 80 % of the cells on the earlier submap's) finds it where it truly lies.
  WayBack turned;
  turned.turn_deg = 4.0;
  turned.about_m = Eigen::Vector2d(60.0, 0.0);
  turned.fixes = true;
  const StreetDrive wide = drive_out_and_back(LoopClosureConfig{}, street_of(8.0), turned);
  LoopClosureConfig narrow_only;
  narrow_only.wide_search_radius_m = 0.0;
  narrow_only.wide_search_yaw_deg = 0.0;
  const StreetDrive narrow = drive_out_and_back(narrow_only, street_of(8.0), turned);
  const Eigen::Vector2d worst = worst_closure_error(wide);
  std::printf("%zu closures (%llu by the wider search; worst %.3f m, %.3f deg), %zu without it\n",
              wide.closures.size(), static_cast<unsigned long long>(wide.counters.wide_closures),
              worst.x(), worst.y(), narrow.closures.size());
  EXPECT_EQ(narrow.closures.size(), 0u);
  ASSERT_GE(wide.closures.size(), 3u);
  EXPECT_EQ(wide.counters.wide_closures, wide.closures.size());
  EXPECT_LT(worst.x(), 0.2);
  EXPECT_LT(worst.y(), 0.2);
}

TEST(LoopCloser, AnotherStreetIsNotTakenForTheOneSeenBefore) {
  // The way back sees other buildings where the way out's were: no closure.
  std::vector<Facade> other = street_of(8.0);
  for (Facade& wall : other) {
    wall.from_m.x() = 160.0 - wall.from_m.x() * 0.83;
    wall.to_m.x() = 160.0 - wall.to_m.x() * 0.83;
  }
  LoopClosureConfig config;
  config.max_candidates = 1;  // each of the way back's submaps against the nearest
  const StreetDrive closed = drive_out_and_back(config, other);
  EXPECT_GT(closed.counters.searches, 0u);
  EXPECT_EQ(closed.closures.size(), 0u);
  EXPECT_EQ(closed.counters.low_score + closed.counters.off_window, closed.counters.searches);
}

// A route that ends 4 m into a submap (under half of it): the run's last metres are matched
// too, at its end (a loop that ends where it began closes there), and the closure says where
// they truly lie.
TEST(LoopCloser, TheLastMetresOfTheRunAreMatchedAtItsEnd) {
  BLOCKMAP_LONG_TEST();
  const std::vector<Facade> walls = street_of(8.0);
  CloserAndPath run{LoopClosureConfig{}};
  LoopCloser& closer = run.closer;
  PathSmoother& path = run.path;
  // 100 m back, then on to 4 m past the next submap finished.
  double end_m = 2.0 * kStreetM;
  std::vector<Pose2> truths;
  for (double s = 0.0; s <= end_m; s += kScanStepM) {
    const Pose2 truth = street_truth_at(s);
    truths.push_back(truth);
    path.add(drifted_back(truth), std::nullopt);
    std::array<LoopClosure, kMaxClosureCandidates> found{};
    if (closer.add_scan(drifted_back(truth), laser_scan_at(walls, truth))) {
      static_cast<void>(closer.find_closures(path, found));
      if (s >= kStreetM + 100.0 && end_m == 2.0 * kStreetM) {
        end_m = s + 4.0;
      }
    }
  }
  const std::uint64_t submaps = closer.counters().submaps;
  const std::uint64_t searches = closer.counters().searches;
  ASSERT_TRUE(closer.finish_last_submap());
  EXPECT_EQ(closer.counters().submaps, submaps + 1);
  EXPECT_FALSE(closer.finish_last_submap()) << "nothing is left open";
  std::array<LoopClosure, kMaxClosureCandidates> found{};
  const std::size_t count = closer.find_closures(path, found);
  EXPECT_GT(closer.counters().searches, searches);
  ASSERT_GE(count, 1u);
  const auto truth_at = [&](TimestampNs stamp_ns) {
    return *std::find_if(truths.begin(), truths.end(),
                         [&](const Pose2& p) { return p.stamp_ns == stamp_ns; });
  };
  for (std::size_t k = 0; k < count; ++k) {
    const Eigen::Vector3d truly =
        pose_in_frame_of(truth_at(found[k].earlier.stamp_ns), truth_at(found[k].later.stamp_ns));
    EXPECT_LT((found[k].measured - truly).head<2>().norm(), 0.2);
  }
}

TEST(LoopCloser, ARouteOfAnyLengthKeepsItsSubmapsInTheirCapacity) {
  LoopClosureConfig config;
  config.max_submaps = 8;
  const StreetDrive closed = drive_out_and_back(config, street_of(8.0));
  EXPECT_GE(closed.counters.submaps, 25u);  // 280 m in 10 m submaps
  EXPECT_LE(closed.submaps, 8u);
  EXPECT_GT(closed.counters.thinnings, 0u);
  EXPECT_LE(closed.memory_bytes, LoopCloser::arena_bytes(config));
}

TEST(LoopCloser, BadConfigurationsAreNamed) {
  const auto problem = [](auto change) {
    LoopClosureConfig config;
    change(config);
    return validate(config);
  };
  EXPECT_EQ(validate(LoopClosureConfig{}), "");
  EXPECT_NE(problem([](LoopClosureConfig& c) { c.cell_m = 0.0; }).find("cell_m"),
            std::string::npos);
  EXPECT_NE(problem([](LoopClosureConfig& c) { c.max_candidates = 5; }).find("max_candidates"),
            std::string::npos);
  EXPECT_NE(problem([](LoopClosureConfig& c) { c.min_score = 1.5; }).find("min_score"),
            std::string::npos);
  EXPECT_NE(problem([](LoopClosureConfig& c) { c.wide_min_score = 0.0; }).find("wide_min_score"),
            std::string::npos);
  EXPECT_NE(
      problem([](LoopClosureConfig& c) { c.last_submap_min_m = -1.0; }).find("last_submap_min_m"),
      std::string::npos);
  EXPECT_NE(problem([](LoopClosureConfig& c) { c.wide_search_yaw_deg = 50.0; }).find("wide_search"),
            std::string::npos);
  EXPECT_NE(problem([](LoopClosureConfig& c) { c.max_range_m = 5000.0; }).find("30000 cells"),
            std::string::npos);
  EXPECT_EQ(problem([](LoopClosureConfig& c) {
              c.enabled = false;
              c.cell_m = 0.0;
            }),
            "");
}

}  // namespace
}  // namespace blockmap::localize
