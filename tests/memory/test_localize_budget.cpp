// Localization takes everything at init: predicting, weighing, resampling, finalizing history
// steps and draining them allocate nothing, step after step.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <optional>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/localize/loop_closer.hpp"
#include "blockmap/localize/map_localizer.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "memory_assertions.hpp"
#include "synthetic_street.hpp"

namespace blockmap::localize {
namespace {

TEST(LocalizeBudget, StepsAllocateNothingAfterInitAndFitTheirBudget) {
  LocalizeConfig config;
  config.particle_count = 500;
  config.history_steps = 64;  // small, so that steps leave the window during the test
  const std::size_t budget = ParticleFilter::arena_bytes(config);
  Arena arena(budget);
  ParticleFilter filter;
  filter.init(arena, config);
  arena.seal();
  EXPECT_LE(arena.used_bytes(), budget);
  std::array<Pose2, 16> drained{};
  std::array<Pose2, 64> window{};
  std::size_t finalized = 0;
  EXPECT_NO_ALLOCATIONS({
    // 60 s of a straight drive east at 1 m/s, odometry at 100 Hz and GPS at 4 Hz.
    for (int k = 1; k <= 6000; ++k) {
      const TimestampNs stamp = TimestampNs{k} * 10'000'000;
      filter.predict(stamp, 0.01, 0.0);
      if (k % 25 == 0) {
        static_cast<void>(filter.update(
            GpsObservation{stamp, 0.01 * k, 0.3 * std::sin(0.01 * k), 1.0, GpsCorrection::kNone}));
      }
      finalized += filter.drain_final(drained);
    }
    static_cast<void>(filter.smoothed_window(window));
    Pose2 pose;
    static_cast<void>(filter.pose_at(TimestampNs{59} * 1'000'000'000, pose));
  });
  EXPECT_GT(finalized, 100u);
  EXPECT_GT(filter.counters().resamplings, 0u);
  EXPECT_LE(filter.memory_bytes(), arena.used_bytes());
  EXPECT_EQ(arena.failed_allocations().value(), 0u);
}

TEST(LocalizeBudget, TheLocalizerAllocatesNothingAfterInitEither) {
  LocalizerConfig config;
  config.filter.particle_count = 300;
  config.filter.history_steps = 32;
  const std::size_t budget = Localizer::arena_bytes(config);
  Arena arena(budget);
  Localizer localizer;
  localizer.init(arena, config);
  arena.seal();
  std::array<Pose3, 32> poses{};
  std::size_t finalized = 0;
  EXPECT_NO_ALLOCATIONS({
    msg::OdometrySample odometry;
    msg::ImuSample imu;
    for (int k = 1; k <= 3000; ++k) {
      const TimestampNs stamp = TimestampNs{k} * 10'000'000;
      odometry.header.stamp_ns = stamp;
      imu.header.stamp_ns = stamp;
      odometry.fore_aft_distance_m = 0.01 * k;
      imu.pitch_rad = 0.02 * std::sin(0.1 * k);
      localizer.on_base(odometry, imu);
      if (k % 25 == 0) {
        static_cast<void>(
            localizer.on_fix(GpsObservation{stamp, 0.01 * k, 0.0, 1.0, GpsCorrection::kNone}, 1.3));
      }
      finalized += localizer.drain_final(poses);
    }
    static_cast<void>(localizer.smoothed_window(poses));
  });
  EXPECT_GT(finalized, 50u);
  EXPECT_LE(localizer.memory_bytes(), arena.used_bytes());
  EXPECT_EQ(arena.failed_allocations().value(), 0u);
}

// The whole path at once: keyframes, thinning when they fill, and Gauss-Newton sweeps.
TEST(LocalizeBudget, ThePathSmootherAllocatesNothingAfterInitAndFitsItsBudget) {
  PathSmootherConfig config;
  config.max_keyframes = 128;  // 400 fixes below: thinned
  const std::size_t budget = PathSmoother::arena_bytes(config);
  Arena arena(budget);
  PathSmoother smoother;
  smoother.init(arena, config);
  arena.seal();
  const auto drive = [&smoother] {
    // 100 s east at 1 m/s, odometry at 100 Hz and GPS at 4 Hz, solved every 10 s.
    for (int k = 1; k <= 10000; ++k) {
      const TimestampNs stamp = TimestampNs{k} * 10'000'000;
      const Pose2 odometry{stamp, 0.01 * k, 0.0, 0.0};
      if (k % 25 == 0) {
        smoother.add(odometry, Eigen::Vector2d(0.01 * k, 0.3 * std::sin(0.01 * k)));
      } else {
        smoother.add(odometry, std::nullopt);
      }
      if (k % 1000 == 0) {
        smoother.solve();
      }
    }
    static_cast<void>(smoother.pose_at(TimestampNs{50} * 1'000'000'000));
  };
  EXPECT_NO_ALLOCATIONS(drive());
  EXPECT_GT(smoother.counters().thinnings, 0u);
  EXPECT_EQ(smoother.counters().fixes, 400u);
  EXPECT_LE(smoother.memory_bytes(), arena.used_bytes());
  EXPECT_LE(arena.used_bytes(), budget);
  EXPECT_EQ(arena.failed_allocations().value(), 0u);
}

// Loop closing: submaps gathered and matched against earlier ones, closures solved with the
// path. The scans are made before the measured loop (a laser's driver fills a buffer it owns).
TEST(LocalizeBudget, LoopClosingAllocatesNothingAfterInitAndFitsItsBudget) {
  using synthetic_street::kScanStepM;
  using synthetic_street::kStreetM;
  LoopClosureConfig loops;
  loops.max_submaps = 16;  // 28 submaps below: thinned
  const PathSmootherConfig path_config;
  const std::size_t budget =
      LoopCloser::arena_bytes(loops) + PathSmoother::arena_bytes(path_config);
  Arena arena(budget);
  LoopCloser closer;
  closer.init(arena, loops);
  PathSmoother path;
  path.init(arena, path_config);
  arena.seal();
  const std::vector<synthetic_street::Facade> street = synthetic_street::street_of(8.0);
  std::vector<Pose2> odometry;
  std::vector<std::vector<Eigen::Vector2d>> scans;
  for (double s = 0.0; s <= 2.0 * kStreetM; s += kScanStepM) {
    const Pose2 truth = synthetic_street::street_truth_at(s);
    odometry.push_back(synthetic_street::drifted_back(truth));
    scans.push_back(synthetic_street::laser_scan_at(street, truth));
  }
  std::array<LoopClosure, kMaxClosureCandidates> found{};
  const auto drive = [&] {
    for (std::size_t i = 0; i < scans.size(); ++i) {
      path.add(odometry[i], std::nullopt);
      if (closer.add_scan(odometry[i], scans[i])) {
        const std::size_t count = closer.find_closures(path, found);
        for (std::size_t k = 0; k < count; ++k) {
          path.close_loop(found[k]);
        }
      }
      if (i % 40 == 0) {
        path.solve();
      }
    }
    path.solve();
  };
  EXPECT_NO_ALLOCATIONS(drive());
  EXPECT_GT(path.closure_count(), 0u);
  EXPECT_GT(closer.counters().thinnings, 0u);
  EXPECT_LE(closer.memory_bytes() + path.memory_bytes(), arena.used_bytes());
  EXPECT_LE(arena.used_bytes(), budget);
  EXPECT_EQ(arena.failed_allocations().value(), 0u);
}

TEST(LocalizeBudget, MapLocalizationAllocatesNothingAfterInitAndFitsItsBudget) {
  // The street's facades as the prior map; placings into the path as the rigid path gives
  // them. The map's grid is built at start-up, after init, in the arena's bytes.
  PriorMapConfig map_config;
  map_config.enabled = true;
  const PathSmootherConfig path_config;
  const std::size_t budget =
      MapLocalizer::arena_bytes(map_config) + PathSmoother::arena_bytes(path_config);
  Arena arena(budget);
  MapLocalizer localizer;
  localizer.init(arena, map_config);
  PathSmoother path;
  path.init(arena, path_config);
  arena.seal();
  const std::vector<synthetic_street::Facade> street = synthetic_street::street_of(8.0);
  const std::vector<MapWall> walls = synthetic_street::map_walls_of(street);
  ASSERT_EQ(localizer.set_map(walls), "");
  std::vector<Pose2> truths;
  std::vector<std::vector<Eigen::Vector2d>> scans;
  for (double s = 0.0; s <= 2.0 * synthetic_street::kStreetM; s += synthetic_street::kScanStepM) {
    truths.push_back(synthetic_street::street_truth_at(s));
    scans.push_back(synthetic_street::laser_scan_at(street, truths.back()));
  }
  localizer.start(truths.front(), truths.front(), 0.05, 0.005);
  const auto drive = [&] {
    for (std::size_t i = 0; i < scans.size(); ++i) {
      path.add(truths[i], std::nullopt);
      MapPlacing placing;
      if (localizer.add_scan(truths[i], scans[i], placing)) {
        path.place(truths[i], truths[i], Eigen::Vector2d(placing.pose.x_m, placing.pose.y_m),
                   placing.information);
      }
      if (i % 40 == 0) {
        path.solve();
      }
    }
    path.solve();
  };
  EXPECT_NO_ALLOCATIONS(drive());
  EXPECT_GT(path.counters().placings, 50u);
  EXPECT_LE(localizer.memory_bytes() + path.memory_bytes(), arena.used_bytes());
  EXPECT_LE(arena.used_bytes(), budget);
  EXPECT_EQ(arena.failed_allocations().value(), 0u);
}

}  // namespace
}  // namespace blockmap::localize
