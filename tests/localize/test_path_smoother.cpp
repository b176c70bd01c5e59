// The whole path at once (localize::PathSmoother): on the synthetic drive of the filter's
// tests (the simulator's receiver: 1.6 m of multipath over 2 s, 1.2 m wandering over 60 s),
// with odometry calibrated as the filter leaves it, the solved path keeps the drive's shape
// and sits where the run's fixes put it on average: off by the receiver's slow error averaged
// over the run, the same everywhere (docs/localize.md, The whole path at once).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "long_test.hpp"
#include "synthetic_drive.hpp"

namespace blockmap::localize {
namespace {

struct SmoothedErrors {
  double rms_m = 0.0;        // against the truth, at every keyframe after the first minute
  double shape_rms_m = 0.0;  // the same with the path's mean error taken out
  Eigen::Vector2d mean_error_m = Eigen::Vector2d::Zero();
  double gps_rms_m = 0.0;
  Eigen::Vector2d receiver_mean_m = Eigen::Vector2d::Zero();  // the fixes' mean error
};

SmoothedErrors smooth_drive(PathSmoother& smoother, const std::vector<synthetic::Sample>& samples,
                            const std::vector<Pose2>& odometry, double settle_s = 60.0) {
  SmoothedErrors errors;
  double gps_sq = 0.0;
  std::size_t fixes = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const synthetic::Sample& s = samples[i];
    std::optional<Eigen::Vector2d> fix;
    if (s.has_fix) {
      fix = Eigen::Vector2d(s.fix.east_m, s.fix.north_m);
      const Eigen::Vector2d error(s.fix.east_m - s.truth.x_m, s.fix.north_m - s.truth.y_m);
      gps_sq += error.squaredNorm();
      errors.receiver_mean_m += error;
      ++fixes;
    }
    smoother.add(odometry[i], fix, 1.0, s.fix.correction);
    if (i % 2000 == 0) {
      smoother.solve();  // as a mapper would, every 20 s
    }
  }
  smoother.solve();
  errors.gps_rms_m = std::sqrt(gps_sq / static_cast<double>(fixes));
  errors.receiver_mean_m /= static_cast<double>(fixes);
  std::vector<Eigen::Vector2d> path_errors;
  for (std::size_t k = 0; k < smoother.keyframe_count(); ++k) {
    const Pose2 p = smoother.pose(k);
    if (seconds_from_ns(p.stamp_ns) < settle_s) {
      continue;
    }
    const auto index = static_cast<std::size_t>(p.stamp_ns / synthetic::kOdometryPeriodNs) - 1;
    const Pose2& truth = samples[index].truth;
    path_errors.emplace_back(p.x_m - truth.x_m, p.y_m - truth.y_m);
  }
  for (const Eigen::Vector2d& e : path_errors) {
    errors.mean_error_m += e / static_cast<double>(path_errors.size());
    errors.rms_m += e.squaredNorm() / static_cast<double>(path_errors.size());
  }
  for (const Eigen::Vector2d& e : path_errors) {
    errors.shape_rms_m +=
        (e - errors.mean_error_m).squaredNorm() / static_cast<double>(path_errors.size());
  }
  errors.rms_m = std::sqrt(errors.rms_m);
  errors.shape_rms_m = std::sqrt(errors.shape_rms_m);
  return errors;
}

struct SmootherFixture {
  explicit SmootherFixture(const PathSmootherConfig& config = {})
      : arena(PathSmoother::arena_bytes(config)) {
    smoother.init(arena, config);
    arena.seal();
  }
  Arena arena;
  PathSmoother smoother;
};

TEST(PathSmoother, TheWholePathSitsWhereTheRunsFixesPutItOnAverage) {
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    synthetic::DriveOptions drive;
    drive.seed = seed;
    const std::vector<synthetic::Sample> samples = synthetic::drive(drive);
    SmootherFixture fixture;
    // Scored from the start: the run's mean receiver error is over every fix.
    const SmoothedErrors e = smooth_drive(
        fixture.smoother, samples, synthetic::calibrated_odometry(samples, drive, 1e-4), 0.0);
    std::printf(
        "seed %llu: GPS %.2f m RMS, its mean error (%.2f, %.2f) m; smoothed %.2f m RMS, "
        "mean (%.2f, %.2f) m, shape %.2f m RMS; %zu keyframes\n",
        static_cast<unsigned long long>(seed), e.gps_rms_m, e.receiver_mean_m.x(),
        e.receiver_mean_m.y(), e.rms_m, e.mean_error_m.x(), e.mean_error_m.y(), e.shape_rms_m,
        fixture.smoother.keyframe_count());
    EXPECT_LT(e.rms_m, 0.4 * e.gps_rms_m) << "seed " << seed;
    // Rigid: the error is one shift for the whole path, and that shift is the fixes' mean
    // error (the receiver's slow error over five minutes), not more.
    EXPECT_LT(e.shape_rms_m, 0.45) << "seed " << seed;
    EXPECT_LT((e.mean_error_m - e.receiver_mean_m).norm(), 0.4) << "seed " << seed;
    EXPECT_EQ(fixture.smoother.counters().thinnings, 0u);
    EXPECT_EQ(fixture.smoother.counters().refused, 0u);
  }
}

// RTK fixes (2 cm, GGA quality 4) carry no slow error of a code receiver's kind: the path
// goes through them, whatever the odometry's drift (here a gyroscope bias left at 0.06 deg/s,
// ten times the calibrated one). The same fixes taken as code fixes let the path keep the
// odometry's bend within the receiver's slow error.
TEST(PathSmoother, RtkFixesPinThePathToCentimetres) {
  synthetic::DriveOptions drive;
  drive.gps_error_rms_m = 0.02;
  drive.gps_multipath_rms_m = 0.015;
  drive.gps_correction = GpsCorrection::kRtkFixed;
  const std::vector<synthetic::Sample> samples = synthetic::drive(drive);
  const std::vector<Pose2> odometry = synthetic::calibrated_odometry(samples, drive, 1e-3);
  SmootherFixture rtk;
  const SmoothedErrors pinned = smooth_drive(rtk.smoother, samples, odometry, 0.0);
  std::vector<synthetic::Sample> as_code = samples;
  for (synthetic::Sample& s : as_code) {
    s.fix.correction = GpsCorrection::kNone;
  }
  SmootherFixture code;
  const SmoothedErrors bent = smooth_drive(code.smoother, as_code, odometry, 0.0);
  std::printf("RTK fixes: path %.3f m RMS, shape %.3f m; as code fixes %.3f m, shape %.3f m\n",
              pinned.rms_m, pinned.shape_rms_m, bent.rms_m, bent.shape_rms_m);
  EXPECT_LT(pinned.rms_m, 0.03);
  EXPECT_GT(bent.rms_m, 3.0 * pinned.rms_m);
}

TEST(PathSmoother, ItIsBetterThanTheParticleFiltersSmoothedPathOnTheSameDrive) {
  BLOCKMAP_LONG_TEST();
  synthetic::DriveOptions drive;
  drive.seed = 2;
  const std::vector<synthetic::Sample> samples = synthetic::drive(drive);
  synthetic::FilterFixture filter;
  const synthetic::RunErrors filtered = synthetic::run(filter.filter, samples, drive);
  SmootherFixture fixture;
  const SmoothedErrors e =
      smooth_drive(fixture.smoother, samples, synthetic::calibrated_odometry(samples, drive, 1e-4));
  std::printf("filter smoothed %.2f m RMS, path smoother %.2f m RMS (GPS %.2f m)\n",
              filtered.smoothed_rms_m, e.rms_m, e.gps_rms_m);
  EXPECT_LT(e.rms_m, 0.75 * filtered.smoothed_rms_m);
}

TEST(PathSmoother, AnOutageIsBridgedByTheOdometry) {
  synthetic::DriveOptions drive;
  drive.seed = 4;
  drive.outage_from_s = 120.0;
  drive.outage_to_s = 180.0;
  const std::vector<synthetic::Sample> samples = synthetic::drive(drive);
  SmootherFixture fixture;
  const SmoothedErrors e =
      smooth_drive(fixture.smoother, samples, synthetic::calibrated_odometry(samples, drive, 1e-4));
  synthetic::DriveOptions whole = drive;
  whole.outage_from_s = whole.outage_to_s = -1.0;
  const std::vector<synthetic::Sample> with_fixes = synthetic::drive(whole);
  SmootherFixture reference;
  const SmoothedErrors r = smooth_drive(reference.smoother, with_fixes,
                                        synthetic::calibrated_odometry(with_fixes, whole, 1e-4));
  std::printf("a minute without GPS: smoothed %.2f m RMS, shape %.2f m; with it %.2f m, %.2f m\n",
              e.rms_m, e.shape_rms_m, r.rms_m, r.shape_rms_m);
  EXPECT_LT(e.shape_rms_m, r.shape_rms_m + 0.35);
  EXPECT_LT(e.rms_m, 0.5 * e.gps_rms_m);
  // A keyframe every metre while no fix came: 72 m at 1.2 m/s.
  EXPECT_GT(fixture.smoother.counters().keyframes_added,
            fixture.smoother.counters().fixes - 240 + 60);
}

TEST(PathSmoother, AFullPathIsThinnedAndStillSolved) {
  synthetic::DriveOptions drive;
  drive.seed = 1;
  const std::vector<synthetic::Sample> samples = synthetic::drive(drive);
  PathSmootherConfig config;
  config.max_keyframes = 256;  // 1,200 fixes: thinned three times
  SmootherFixture fixture(config);
  const SmoothedErrors e =
      smooth_drive(fixture.smoother, samples, synthetic::calibrated_odometry(samples, drive, 1e-4));
  std::printf("256 keyframes: %zu kept, %llu thinnings, smoothed %.2f m RMS, shape %.2f m\n",
              fixture.smoother.keyframe_count(),
              static_cast<unsigned long long>(fixture.smoother.counters().thinnings), e.rms_m,
              e.shape_rms_m);
  EXPECT_GE(fixture.smoother.counters().thinnings, 2u);
  EXPECT_LE(fixture.smoother.keyframe_count(), 256u);
  EXPECT_EQ(fixture.smoother.counters().fixes, 1200u);
  EXPECT_LT(e.shape_rms_m, 0.4);
  EXPECT_LT(e.rms_m, 0.4 * e.gps_rms_m);
  // The newest keyframe is the last odometry pose.
  EXPECT_EQ(fixture.smoother.pose(fixture.smoother.keyframe_count() - 1).stamp_ns,
            samples.back().stamp_ns);
}

TEST(PathSmoother, PosesBetweenKeyframesAreInterpolatedAndTimeDoesNotGoBack) {
  SmootherFixture fixture;
  PathSmoother& smoother = fixture.smoother;
  // East at 1 m/s, a fix each second on the true path.
  for (int k = 0; k <= 10; ++k) {
    const TimestampNs stamp = TimestampNs{k} * 1'000'000'000;
    smoother.add(Pose2{stamp, 1.0 * k, 0.0, 0.0}, Eigen::Vector2d(100.0 + k, 50.0));
  }
  smoother.add(Pose2{TimestampNs{5} * 1'000'000'000, 5.0, 0.0, 0.0}, std::nullopt);
  EXPECT_EQ(smoother.counters().refused, 1u);
  smoother.solve();
  ASSERT_EQ(smoother.keyframe_count(), 11u);
  const Pose2 middle = smoother.pose_at(2'500'000'000);
  EXPECT_NEAR(middle.x_m, 102.5, 0.05);
  EXPECT_NEAR(middle.y_m, 50.0, 0.05);
  EXPECT_NEAR(middle.yaw_rad, 0.0, 1e-3);
  EXPECT_NEAR(smoother.pose_at(-1).x_m, 100.0, 0.05);
  EXPECT_NEAR(smoother.pose_at(TimestampNs{20} * 1'000'000'000).x_m, 110.0, 0.05);
}

// What was drawn with another pose is moved by correction(): the rigid motion from the drawn
// pose to the solved one.
TEST(PathSmoother, TheCorrectionTakesTheDrawnPoseToTheSolvedOne) {
  SmootherFixture fixture;
  PathSmoother& smoother = fixture.smoother;
  // The truth runs east along y = 0; the map was drawn 2 m north and turned by 0.1 rad.
  for (int k = 0; k <= 40; ++k) {
    const TimestampNs stamp = TimestampNs{k} * 250'000'000;
    const double x_m = 0.25 * k;
    const Pose2 drawn{stamp, x_m, 2.0, 0.1};
    smoother.add(Pose2{stamp, x_m, 0.0, 0.0}, drawn, Eigen::Vector2d(x_m, 0.0));
  }
  smoother.solve();
  for (std::size_t i = 0; i < smoother.keyframe_count(); ++i) {
    const PlanarCorrection c = smoother.correction(i);
    const Pose2 moved = c.apply(smoother.drawn(i));
    const Pose2 solved = smoother.pose(i);
    EXPECT_NEAR(moved.x_m, solved.x_m, 1e-9);
    EXPECT_NEAR(moved.y_m, solved.y_m, 1e-9);
    EXPECT_NEAR(moved.yaw_rad, solved.yaw_rad, 1e-9);
    EXPECT_NEAR(solved.y_m, 0.0, 0.05);
    EXPECT_NEAR(c.yaw_rad, -0.1, 0.01);
  }
}

// Ties between passes. Out along a wall and back: the drawn map put the robot where the
// receiver did, 1 m north on the way out and 1 m south on the way back (its slow error), and
// the odometry is trusted little (a loose gyroscope), so the fixes alone bend the path
// with the receiver. The wall 10 m north is drawn twice, 2 m apart. A tie says the two looks
// are one wall: moved by the solved path, they must agree.
struct OutAndBack {
  static constexpr double kSpeedMps = 1.2;
  static constexpr double kLengthM = 60.0;
  static constexpr double kWallNorthM = 10.0;
  static constexpr double kBiasM = 1.0;
  static constexpr TimestampNs kFixPeriodNs = 250'000'000;
  static constexpr TimestampNs kTurnNs = 20 * kNanosecondsPerSecond;  // standing at the end

  // The truth at `stamp_ns`, and the receiver's slow error then (north).
  static Pose2 truth(TimestampNs stamp_ns, double& bias_north_m) {
    const double t_s = seconds_from_ns(stamp_ns);
    const double leg_s = kLengthM / kSpeedMps;
    const double turn_s = seconds_from_ns(kTurnNs);
    if (t_s <= leg_s) {
      bias_north_m = kBiasM;
      return Pose2{stamp_ns, kSpeedMps * t_s, 0.0, 0.0};
    }
    if (t_s <= leg_s + turn_s) {
      const double f = (t_s - leg_s) / turn_s;
      bias_north_m = kBiasM * (1.0 - 2.0 * f);
      return Pose2{stamp_ns, kLengthM, 0.0, synthetic::kPi * f};
    }
    bias_north_m = -kBiasM;
    return Pose2{stamp_ns, kLengthM - kSpeedMps * (t_s - leg_s - turn_s), 0.0, synthetic::kPi};
  }
  static TimestampNs end_ns() {
    return static_cast<TimestampNs>((2.0 * kLengthM / kSpeedMps) * 1e9) + kTurnNs;
  }
  // When the robot passes x = 30 m on the way out and on the way back.
  static TimestampNs out_ns() { return static_cast<TimestampNs>(30.0 / kSpeedMps * 1e9); }
  static TimestampNs back_ns() {
    return static_cast<TimestampNs>((kLengthM + 30.0) / kSpeedMps * 1e9) + kTurnNs;
  }

  static PathSmootherConfig loose_odometry() {
    PathSmootherConfig config;
    config.yaw_sigma_per_sqrt_m = 0.02;
    config.across_sigma_per_sqrt_m = 0.1;
    config.fix_sigma_m = 0.5;
    return config;
  }

  // Drives it; a tie when `tied`.
  static void drive(PathSmoother& smoother, bool tied) {
    for (TimestampNs t = 0; t <= end_ns(); t += kFixPeriodNs) {
      double bias_north_m = 0.0;
      const Pose2 pose = truth(t, bias_north_m);
      Pose2 drawn = pose;
      drawn.y_m += bias_north_m;
      smoother.add(pose, drawn, Eigen::Vector2d(pose.x_m, pose.y_m + bias_north_m));
      if (t % (10 * kNanosecondsPerSecond) == 0) {
        smoother.solve();
      }
    }
    if (tied) {
      EXPECT_TRUE(smoother.tie(7, look(out_ns(), kWallNorthM + kBiasM),
                               look(back_ns(), kWallNorthM - kBiasM)));
    }
    smoother.solve();
  }
  static WallLook look(TimestampNs stamp_ns, double north_m) {
    // Seen from the south: the normal towards the robot.
    return WallLook{stamp_ns, Eigen::Vector2d(0.0, -1.0), Eigen::Vector2d(30.0, north_m)};
  }
  // Where the solved path puts a look: moved by the correction of the keyframe nearest it.
  static double moved_north_m(const PathSmoother& smoother, const WallLook& look) {
    std::size_t nearest = 0;
    for (std::size_t i = 0; i < smoother.keyframe_count(); ++i) {
      if (std::abs(smoother.pose(i).stamp_ns - look.stamp_ns) <
          std::abs(smoother.pose(nearest).stamp_ns - look.stamp_ns)) {
        nearest = i;
      }
    }
    return smoother.correction(nearest).apply(look.point_m).y();
  }
};

TEST(PathSmootherTies, AWallSeenOnTwoPassesIsOneWallOnTheSolvedPath) {
  double apart_m[2] = {};
  double middle_m[2] = {};
  for (const bool tied : {false, true}) {
    SmootherFixture fixture(OutAndBack::loose_odometry());
    OutAndBack::drive(fixture.smoother, tied);
    const double out_m =
        OutAndBack::moved_north_m(fixture.smoother, OutAndBack::look(OutAndBack::out_ns(), 11.0));
    const double back_m =
        OutAndBack::moved_north_m(fixture.smoother, OutAndBack::look(OutAndBack::back_ns(), 9.0));
    apart_m[tied ? 1 : 0] = std::abs(out_m - back_m);
    middle_m[tied ? 1 : 0] = 0.5 * (out_m + back_m);
    std::printf("%s: the wall at %.2f m and %.2f m north; %llu conjugate-gradient steps\n",
                tied ? "tied" : "without the tie", out_m, back_m,
                static_cast<unsigned long long>(fixture.smoother.counters().cg_steps));
    EXPECT_EQ(fixture.smoother.tie_count(), tied ? 1u : 0u);
    EXPECT_EQ(fixture.smoother.counters().cg_steps > 0, tied);
  }
  // Without the tie the passes keep a quarter of the receiver's 2 m apart;
  // with it they are one wall, where the two passes' fixes put it on average (the truth).
  EXPECT_GT(apart_m[0], 0.4);
  EXPECT_LT(apart_m[1], 0.1);
  EXPECT_NEAR(middle_m[1], OutAndBack::kWallNorthM, 0.3);
}

// A loop closure on the same drive: the lasers matched the way back at x = 30 m to the way out
// there, and say the two poses are the same place turned half round. The solved path holds
// them so, wherever the receiver's slow error put each pass.
TEST(PathSmootherClosures, ALoopClosureHoldsTwoPassesWhereTheLasersPutThem) {
  double apart_m[2] = {};
  for (const bool closed : {false, true}) {
    SmootherFixture fixture(OutAndBack::loose_odometry());
    OutAndBack::drive(fixture.smoother, false);
    double bias_north_m = 0.0;
    LoopClosure closure;
    closure.earlier = OutAndBack::truth(OutAndBack::out_ns(), bias_north_m);
    closure.later = OutAndBack::truth(OutAndBack::back_ns(), bias_north_m);
    closure.measured = Eigen::Vector3d(0.0, 0.0, synthetic::kPi);
    closure.information = Eigen::Vector3d(400.0, 400.0, 1e4).asDiagonal();
    if (closed) {
      fixture.smoother.close_loop(closure);
      fixture.smoother.solve();
    }
    const Pose2 out = fixture.smoother.solved_pose(closure.earlier);
    const Pose2 back = fixture.smoother.solved_pose(closure.later);
    apart_m[closed ? 1 : 0] = std::hypot(out.x_m - back.x_m, out.y_m - back.y_m);
    std::printf("%s: the two passes at x = 30 m lie %.3f m apart\n",
                closed ? "closed" : "without the closure", apart_m[closed ? 1 : 0]);
    EXPECT_EQ(fixture.smoother.closure_count(), closed ? 1u : 0u);
  }
  EXPECT_GT(apart_m[0], 0.4);
  EXPECT_LT(apart_m[1], 0.05);
}

TEST(PathSmootherClosures, AFullSetDropsEveryOtherOfTheOlderHalf) {
  PathSmootherConfig config;
  config.max_closures = 8;
  SmootherFixture fixture(config);
  fixture.smoother.add(Pose2{0, 0.0, 0.0, 0.0}, std::nullopt);
  for (int k = 0; k < 9; ++k) {
    fixture.smoother.close_loop(LoopClosure{Pose2{k, 0.0, 0.0, 0.0}, Pose2{k, 0.0, 0.0, 0.0}});
  }
  EXPECT_EQ(fixture.smoother.closure_count(), 7u);
  EXPECT_EQ(fixture.smoother.counters().closures, 9u);
  EXPECT_EQ(fixture.smoother.counters().closures_dropped, 2u);
}

TEST(PathSmootherTies, OnePassRefreshesItsTie) {
  PathSmootherConfig config;
  config.max_ties = 2;
  SmootherFixture fixture(config);
  PathSmoother& smoother = fixture.smoother;
  const WallLook earlier{0, Eigen::Vector2d(0.0, 1.0), Eigen::Vector2d(0.0, 5.0)};
  EXPECT_FALSE(smoother.tie(1, earlier, earlier)) << "no keyframes yet";
  smoother.add(Pose2{0, 0.0, 0.0, 0.0}, Eigen::Vector2d(0.0, 0.0));
  const auto later = [](TimestampNs stamp_ns) {
    // Seen from the other side: the tie turns it to the earlier look's side.
    return WallLook{stamp_ns, Eigen::Vector2d(0.0, -1.0), Eigen::Vector2d(3.0, 5.2)};
  };
  EXPECT_TRUE(smoother.tie(1, earlier, later(100 * kNanosecondsPerSecond)));
  EXPECT_TRUE(smoother.tie(1, earlier, later(110 * kNanosecondsPerSecond)));  // the same pass
  EXPECT_EQ(smoother.tie_count(), 1u);
  EXPECT_EQ(smoother.counters().ties_refreshed, 1u);
  EXPECT_TRUE(smoother.tie(1, earlier, later(200 * kNanosecondsPerSecond)));  // another pass
  EXPECT_EQ(smoother.tie_count(), 2u);
  EXPECT_EQ(smoother.counters().ties, 2u);
  EXPECT_EQ(smoother.counters().ties_dropped, 0u);
}

// Full, the two most alike of the kept ties and the new one hold the same stretches of path
// to each other: the new one is dropped when it is one of them, else the older of the two
// gives it its place, so that a long run's later passes are tied too.
TEST(PathSmootherTies, AFullSetGivesUpTheMostAlikeTie) {
  PathSmootherConfig config;
  config.max_ties = 3;
  SmootherFixture fixture(config);
  PathSmoother& smoother = fixture.smoother;
  smoother.add(Pose2{0, 0.0, 0.0, 0.0}, Eigen::Vector2d(0.0, 0.0));
  const auto look = [](double stamp_s, const Eigen::Vector2d& normal) {
    return WallLook{static_cast<TimestampNs>(stamp_s * 1e9), normal, Eigen::Vector2d(0.0, 5.0)};
  };
  const Eigen::Vector2d north(0.0, 1.0);
  const Eigen::Vector2d east(1.0, 0.0);
  // Two ties of the same two stretches (5 s apart at most) and one of a third pass.
  ASSERT_TRUE(smoother.tie(1, look(0.0, north), look(100.0, north)));
  ASSERT_TRUE(smoother.tie(2, look(5.0, north), look(104.0, north)));
  ASSERT_TRUE(smoother.tie(3, look(0.0, north), look(300.0, north)));
  // Within 2 s of the first: it is the spare one.
  EXPECT_FALSE(smoother.tie(4, look(2.0, north), look(101.0, north)));
  EXPECT_EQ(smoother.counters().ties_dropped, 1u);
  // A fourth pass, 200 s from every kept one: the first (older than the second) goes.
  EXPECT_TRUE(smoother.tie(5, look(0.0, north), look(500.0, north)));
  EXPECT_EQ(smoother.tie_count(), 3u);
  EXPECT_EQ(smoother.counters().ties_replaced, 1u);
  // The second is still kept: a later look of its pass refreshes it.
  EXPECT_TRUE(smoother.tie(2, look(5.0, north), look(110.0, north)));
  EXPECT_EQ(smoother.counters().ties_refreshed, 1u);
  // A wall across the others is like none of them: the most alike pair is now the second
  // (later look at 110 s) and the third (300 s), 190 s apart, and the second goes.
  EXPECT_TRUE(smoother.tie(6, look(1.0, east), look(103.0, east)));
  EXPECT_EQ(smoother.counters().ties_replaced, 2u);
  // The first is gone: a later look of its pass is a new tie, not a refresh. It is 190 s
  // from the third, nearer than any two kept ones (the third and the fifth, 200 s): it is
  // the spare one.
  EXPECT_FALSE(smoother.tie(1, look(0.0, north), look(110.0, north)));
  EXPECT_EQ(smoother.counters().ties_refreshed, 1u);
  EXPECT_EQ(smoother.counters().ties_dropped, 2u);
  EXPECT_EQ(smoother.counters().ties, 5u);
  EXPECT_EQ(smoother.tie_count(), 3u);
}

// A straight 200 m drive east, a keyframe and a true fix every metre, whose odometry turns
// 3 degrees too far at 100 m. The worst heading of the solved path more than 5 m from there.
double heading_off_past_a_kink_rad(bool note_the_kink) {
  PathSmootherConfig config;
  config.matched_yaw_sigma_per_sqrt_m = 0.0005;  // a scan matcher's turn
  config.yaw_sigma_per_sqrt_m = 0.05;            // the odometry's alone
  Arena arena(PathSmoother::arena_bytes(config));
  PathSmoother smoother;
  smoother.init(arena, config);
  arena.seal();
  const double kink_rad = 3.0 * synthetic::kPi / 180.0;
  for (int metre = 0; metre <= 200; ++metre) {
    const double x_m = metre;
    Pose2 odometry{static_cast<TimestampNs>(metre) * kNanosecondsPerSecond, x_m, 0.0, 0.0};
    if (metre > 100) {
      odometry.x_m = 100.0 + (x_m - 100.0) * std::cos(kink_rad);
      odometry.y_m = (x_m - 100.0) * std::sin(kink_rad);
      odometry.yaw_rad = kink_rad;
    }
    if (note_the_kink && metre > 98 && metre <= 102) {
      smoother.note_dead_reckoning(1.0, 1.0, 0.0);  // no scan matched over these metres
    } else {
      smoother.note_dead_reckoning(0.0, 0.0, 1.0);  // every scan matched
    }
    smoother.add(odometry, Eigen::Vector2d(x_m, 0.0));
  }
  for (int i = 0; i < 4; ++i) {
    smoother.solve();
  }
  double worst_rad = 0.0;
  for (std::size_t k = 0; k < smoother.keyframe_count(); ++k) {
    const Pose2 pose = smoother.pose(k);
    if (std::abs(pose.x_m - 100.0) > 5.0) {
      worst_rad = std::max(worst_rad, std::abs(std::remainder(pose.yaw_rad, 2.0 * synthetic::kPi)));
    }
  }
  return worst_rad;
}

TEST(PathSmoother, TheOdometrysOwnStretchesTakeItsTurnErrors) {
  // Told which metres the odometry carried alone, the solved path turns there and stays
  // straight on either side; told that every metre was matched, it spreads the 3 degrees
  // over the drive.
  const double told = heading_off_past_a_kink_rad(true);
  const double all_matched = heading_off_past_a_kink_rad(false);
  std::printf("heading off away from the kink: %.2f deg told, %.2f deg all matched\n",
              told * 180.0 / synthetic::kPi, all_matched * 180.0 / synthetic::kPi);
  EXPECT_LT(told, 0.3 * synthetic::kPi / 180.0);
  EXPECT_GT(all_matched, 3.0 * told);
}

// An L-shaped drive (60 m east, then 60 m north) started at a known pose, placed by a prior
// map whose frame sits (1.0, -0.7) m off the start's, as an earlier run's receiver would have
// put it: the first leg's walls pin the position across it (north), the second's across it
// (east). The worst keyframe's distance from the truth, and the slow error at the end.
struct PlacedDrive {
  double worst_m = 0.0;
  Eigen::Vector2d end_slow_error_m = Eigen::Vector2d::Zero();
};

PlacedDrive drive_placed_on_an_offset_map(bool carry_offset) {
  const Eigen::Vector2d map_offset_m(1.0, -0.7);
  SmootherFixture fixture;
  PathSmoother& smoother = fixture.smoother;
  smoother.hold_first(0.05, 0.005);
  if (carry_offset) {
    smoother.carry_map_offset(1.5, 300.0);
  }
  std::vector<Pose2> truths;
  for (int i = 0; i <= 240; ++i) {
    const bool east = i <= 120;
    const double along_m = 0.5 * (east ? i : i - 120);
    truths.push_back(Pose2{static_cast<TimestampNs>(i + 1) * 500'000'000, east ? along_m : 60.0,
                           east ? 0.0 : along_m, east ? 0.0 : 0.5 * synthetic::kPi});
  }
  for (std::size_t i = 0; i < truths.size(); ++i) {
    const Pose2& truth = truths[i];
    smoother.note_dead_reckoning(0.0, 0.0, 0.5);  // every scan matched, as on a mapper's path
    if (i % 4 != 0 || i == 0) {
      smoother.add(truth, std::nullopt);
      continue;
    }
    const Eigen::Matrix2d information = i <= 120 ? Eigen::Vector2d(0.0, 100.0).asDiagonal()
                                                 : Eigen::Vector2d(100.0, 0.0).asDiagonal();
    smoother.place(truth, truth, Eigen::Vector2d(truth.x_m, truth.y_m) + map_offset_m, information);
  }
  for (int i = 0; i < 3; ++i) {
    smoother.solve();
  }
  PlacedDrive result;
  for (std::size_t k = 0; k < smoother.keyframe_count(); ++k) {
    const Pose2 pose = smoother.pose(k);
    const auto i = static_cast<std::size_t>(pose.stamp_ns / 500'000'000) - 1;
    result.worst_m =
        std::max(result.worst_m, std::hypot(pose.x_m - truths[i].x_m, pose.y_m - truths[i].y_m));
  }
  result.end_slow_error_m = smoother.slow_error(truths.back());
  return result;
}

TEST(PathSmootherPlacings, AMapsOwnOffsetIsCarriedAndThePathKeepsItsStartsFrame) {
  // Carried, the offset goes into the slow error and the path stays where its start and
  // motion put it; placed as exact, the map pulls each leg across to its own frame and the
  // path bends at the held start.
  const PlacedDrive carried = drive_placed_on_an_offset_map(true);
  const PlacedDrive exact = drive_placed_on_an_offset_map(false);
  std::printf("worst keyframe %.3f m carried (slow error at the end %.2f, %.2f m), %.3f m not\n",
              carried.worst_m, carried.end_slow_error_m.x(), carried.end_slow_error_m.y(),
              exact.worst_m);
  // The offset's own prior (1.5 m) and the matched motion's bend share the last tenths.
  EXPECT_LT(carried.worst_m, 0.2);
  EXPECT_NEAR(carried.end_slow_error_m.x(), 1.0, 0.2);
  EXPECT_NEAR(carried.end_slow_error_m.y(), -0.7, 0.2);
  EXPECT_GT(exact.worst_m, 1.0);
}

// A drive 120 m east started at a known pose, on a map whose walls pin it across the street
// (north) every 2 m, the map's offset carried. The first 6 s are the odometry's alone, and
// its gyroscope's bias (0.3 degrees a second, not yet learnt) turns it 1.8 degrees; the
// matched scans after hold that heading. The solved path's worst heading past the start.
double heading_off_after_an_unlearnt_bias_rad(double unlearnt_sigma_radps) {
  PathSmootherConfig config;
  config.unlearnt_yaw_rate_bias_sigma_radps = unlearnt_sigma_radps;
  SmootherFixture fixture(config);
  PathSmoother& smoother = fixture.smoother;
  smoother.hold_first(0.05, 0.005);
  smoother.carry_map_offset(1.5, 300.0);
  const double bias_radps = 0.3 * synthetic::kPi / 180.0;
  const double alone_s = 6.0;
  Pose2 odometry{500'000'000, 0.0, 0.0, 0.0};
  for (int i = 0; i <= 240; ++i) {
    const double t_s = 0.5 * (i + 1);
    if (i > 0) {
      odometry.yaw_rad = -bias_radps * std::min(t_s, alone_s);
      odometry.x_m += 0.5 * std::cos(odometry.yaw_rad);
      odometry.y_m += 0.5 * std::sin(odometry.yaw_rad);
      odometry.stamp_ns = static_cast<TimestampNs>(i + 1) * 500'000'000;
    }
    const bool alone = t_s <= alone_s;
    smoother.note_dead_reckoning(alone ? 0.5 : 0.0, alone ? 0.5 : 0.0, alone ? 0.0 : 0.5);
    const double true_x_m = 0.5 * i;
    if (i % 4 != 0 || i == 0) {
      smoother.add(odometry, std::nullopt);
      continue;
    }
    smoother.place(odometry, odometry, Eigen::Vector2d(true_x_m, 0.0),
                   Eigen::Vector2d(0.0, 100.0).asDiagonal());
  }
  for (int i = 0; i < 3; ++i) {
    smoother.solve();
  }
  double worst_rad = 0.0;
  for (std::size_t k = 0; k < smoother.keyframe_count(); ++k) {
    const Pose2 pose = smoother.pose(k);
    if (seconds_from_ns(pose.stamp_ns) > 2.0 * alone_s) {
      worst_rad = std::max(worst_rad, std::abs(pose.yaw_rad));
    }
  }
  return worst_rad;
}

TEST(PathSmootherPlacings, TheGyroscopesBiasBeforeItIsLearntLetsTheMapTurnTheStart) {
  // Weighed with the bias it may still carry, the first seconds' turn gives way to the map's
  // walls; weighed as a calibrated gyroscope, it holds most of its 1.8 degrees against them.
  const double weighed = heading_off_after_an_unlearnt_bias_rad(0.01);
  const double calibrated = heading_off_after_an_unlearnt_bias_rad(0.0);
  std::printf("heading off past the start: %.2f deg with the bias weighed, %.2f deg without\n",
              weighed * 180.0 / synthetic::kPi, calibrated * 180.0 / synthetic::kPi);
  EXPECT_LT(weighed, 0.1 * synthetic::kPi / 180.0);
  EXPECT_GT(calibrated, 3.0 * weighed);
}

TEST(PathSmoother, BadConfigurationsAreNamed) {
  PathSmootherConfig config;
  EXPECT_EQ(validate(config), "");
  config.max_keyframes = 2;
  EXPECT_NE(validate(config).find("max_keyframes"), std::string::npos);
  config = {};
  config.bias_time_s = 0.0;
  EXPECT_NE(validate(config).find("bias_time_s"), std::string::npos);
  config = {};
  config.across_sigma_per_sqrt_m = std::nan("");
  EXPECT_NE(validate(config).find("sigmas"), std::string::npos);
  config = {};
  config.matched_yaw_sigma_per_sqrt_m = 0.0;
  EXPECT_NE(validate(config).find("sigmas"), std::string::npos);
  config = {};
  config.iterations = 0;
  EXPECT_NE(validate(config).find("iterations"), std::string::npos);
  config = {};
  config.rtk_fixed_sigma_m = 0.0;
  EXPECT_NE(validate(config).find("rtk_fixed_sigma_m"), std::string::npos);
  config = {};
  config.tie_offset_sigma_m = 0.0;
  EXPECT_NE(validate(config).find("tie_offset_sigma_m"), std::string::npos);
  config.max_ties = 0;  // no ties: their sigmas are not used
  EXPECT_EQ(validate(config), "");
  config = {};
  config.unlearnt_yaw_rate_bias_sigma_radps = -0.01;
  EXPECT_NE(validate(config).find("unlearnt_yaw_rate_bias_sigma_radps"), std::string::npos);
  config = {};
  config.unlearnt_yaw_rate_bias_time_s = 0.0;
  EXPECT_NE(validate(config).find("unlearnt_yaw_rate_bias_time_s"), std::string::npos);
}

}  // namespace
}  // namespace blockmap::localize
