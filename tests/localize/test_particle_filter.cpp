// The particle filter on a synthetic drive whose truth is known: a loop around a block with
// the simulator's error models (tyre scale, gyroscope bias and noise, slip, a GPS error of 2 m
// RMS: multipath correlated over 2 s and a slow part that wanders with a 60 s correlation time).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/random.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "long_test.hpp"
#include "synthetic_drive.hpp"

namespace blockmap::localize {
namespace {

using namespace synthetic;  // NOLINT(google-build-using-namespace): the drive and its scoring

// Tests of behaviour, not of the default's accuracy, run 1,000 particles: a quarter of the
// time, which counts under QEMU.
LocalizeConfig behaviour_config() {
  LocalizeConfig config;
  config.particle_count = 1000;
  return config;
}

TEST(ParticleFilter, FindsItsHeadingAndTracksTheLoopBetterThanGps) {
  BLOCKMAP_LONG_TEST();
  // Three drives (their own seeds for the drive and the filter): one drive's figure moves by
  // a tenth with the filter's random draws, the mean of three by much less.
  constexpr int kDrives = 3;
  RunErrors mean;
  std::uint64_t recoveries = 0;
  for (int seed = 1; seed <= kDrives; ++seed) {
    DriveOptions options;
    options.seed = static_cast<std::uint64_t>(seed);
    LocalizeConfig config;
    config.seed = static_cast<std::uint64_t>(seed);
    FilterFixture fixture(config);
    const RunErrors errors = run(fixture.filter, drive(options), options);
    std::printf(
        "drive %d: filter %.2f m, smoothed %.2f m, gps %.2f m, heading %.2f deg, smoothed %.2f "
        "deg\n",
        seed, errors.filter_rms_m, errors.smoothed_rms_m, errors.gps_rms_m, errors.heading_rms_deg,
        errors.smoothed_heading_rms_deg);
    mean.filter_rms_m += errors.filter_rms_m / kDrives;
    mean.smoothed_rms_m += errors.smoothed_rms_m / kDrives;
    mean.gps_rms_m += errors.gps_rms_m / kDrives;
    mean.heading_rms_deg += errors.heading_rms_deg / kDrives;
    mean.smoothed_heading_rms_deg += errors.smoothed_heading_rms_deg / kDrives;
    recoveries += fixture.filter.counters().recoveries;
  }
  // The targets for the smoothed trajectory: at most half the GPS error, 2 deg of
  // heading. (Over ten drives: bench_localize, docs/localize.md.)
  EXPECT_LT(mean.filter_rms_m, mean.gps_rms_m);
  EXPECT_LT(mean.smoothed_rms_m, mean.filter_rms_m);
  EXPECT_LT(mean.smoothed_rms_m, 0.5 * mean.gps_rms_m);
  EXPECT_LT(mean.smoothed_heading_rms_deg, 2.0);
  EXPECT_LT(mean.heading_rms_deg, 3.0);
  EXPECT_EQ(recoveries, 0u);
}

// A carrier-phase (RTK) receiver: 2 cm of error, of which 1.5 cm multipath. The fixes say
// so (GGA quality 4), and the filter takes them at their word: the particles start within a
// few centimetres of the first fix and stay there, where a code fix's floor (min_gps_sigma_m)
// would have kept them half a metre wide.
TEST(ParticleFilter, RtkFixesHoldThePoseToCentimetres) {
  BLOCKMAP_LONG_TEST();
  DriveOptions options;
  options.gps_error_rms_m = 0.02;
  options.gps_multipath_rms_m = 0.015;
  options.gps_correction = GpsCorrection::kRtkFixed;
  LocalizeConfig config;
  config.particle_count = 2000;  // the mapper's
  FilterFixture fixture(config);
  const RunErrors errors = run(fixture.filter, drive(options), options, 10.0);
  std::printf(
      "RTK: filter %.3f m, smoothed %.3f m, gps %.3f m, heading %.2f deg, smoothed %.2f deg\n",
      errors.filter_rms_m, errors.smoothed_rms_m, errors.gps_rms_m, errors.heading_rms_deg,
      errors.smoothed_heading_rms_deg);
  EXPECT_LT(errors.filter_rms_m, 0.05);
  EXPECT_LT(errors.smoothed_rms_m, 0.05);
  EXPECT_LT(errors.heading_rms_deg, 0.5);
  EXPECT_LT(errors.smoothed_heading_rms_deg, 0.5);
  EXPECT_EQ(fixture.filter.counters().recoveries, 0u);
}

TEST(ParticleFilter, LearnsTheGyroscopeBias) {
  // The survivors carry the gyroscope's bias. (Their distance scale stays near 1 on this loop:
  // 1.5 % of a 60 m leg is less than the GPS error; docs/localize.md.)
  DriveOptions options;
  FilterFixture fixture(behaviour_config());
  static_cast<void>(run(fixture.filter, drive(options), options));
  EXPECT_NEAR(fixture.filter.mean_yaw_rate_bias_radps(), options.yaw_rate_bias_radps, 0.0015);
}

TEST(ParticleFilter, BridgesAThirtySecondOutage) {
  DriveOptions options;
  options.outage_from_s = 150.0;
  options.outage_to_s = 180.0;
  FilterFixture fixture(behaviour_config());
  const RunErrors errors = run(fixture.filter, drive(options), options);
  std::printf("worst during the outage %.2f m\n", errors.worst_in_outage_m);
  EXPECT_LT(errors.worst_in_outage_m, 5.0);
  EXPECT_EQ(fixture.filter.counters().recoveries, 0u);
  EXPECT_EQ(fixture.filter.counters().fixes_rejected, 0u);
}

TEST(ParticleFilter, LeavesOutAMultipathJumpAndStartsOverWhenGpsDisagreesForLong) {
  DriveOptions options;
  options.duration_s = 120.0;
  std::vector<Sample> samples = drive(options);
  const LocalizeConfig config = behaviour_config();
  FilterFixture fixture(config);
  ParticleFilter& filter = fixture.filter;
  std::size_t k = 0;
  const auto feed_until = [&](double t_s) {
    for (; k < samples.size() && static_cast<double>(samples[k].stamp_ns) * 1e-9 < t_s; ++k) {
      filter.predict(samples[k].stamp_ns, samples[k].distance_m, samples[k].yaw_rate_radps);
      if (samples[k].has_fix) {
        static_cast<void>(filter.update(samples[k].fix));
      }
    }
  };
  feed_until(80.0);
  // One fix 40 m off: left out, the estimate stays.
  const Pose2 before = filter.estimate();
  GpsObservation jump = samples[k].fix;
  jump.stamp_ns = before.stamp_ns;
  jump.east_m = before.x_m + 40.0;
  EXPECT_EQ(filter.update(jump), GpsOutcome::kRejected);
  // (The odometry since the last base sample's batch is applied to the particles at a fix,
  // with its noise: the estimate moves by that noise, under a millimetre, not by the jump.)
  EXPECT_LT(std::hypot(filter.estimate().x_m - before.x_m, filter.estimate().y_m - before.y_m),
            0.005);
  // Every fix 50 m off from now on: after max_rejected_fixes the filter starts over there.
  GpsOutcome last = GpsOutcome::kUsed;
  std::uint32_t rejected = 0;
  for (; k < samples.size() && last != GpsOutcome::kRecovered; ++k) {
    filter.predict(samples[k].stamp_ns, samples[k].distance_m, samples[k].yaw_rate_radps);
    if (samples[k].has_fix) {
      GpsObservation off = samples[k].fix;
      off.north_m += 50.0;
      last = filter.update(off);
      rejected += last == GpsOutcome::kRejected ? 1 : 0;
    }
  }
  EXPECT_EQ(last, GpsOutcome::kRecovered);
  EXPECT_EQ(rejected + 2, config.max_rejected_fixes);  // the jump, then these, then recovery
  const Pose2 after = filter.estimate();
  EXPECT_LT(std::hypot(after.x_m - samples[k - 1].truth.x_m,
                       after.y_m - (samples[k - 1].truth.y_m + 50.0)),
            6.0);
}

TEST(ParticleFilter, TheSameInputsAndSeedGiveTheSameTrajectoryBitForBit) {
  DriveOptions options;
  options.duration_s = 90.0;
  const std::vector<Sample> samples = drive(options);
  FilterFixture a(behaviour_config());
  FilterFixture b(behaviour_config());
  for (const Sample& s : samples) {
    for (ParticleFilter* f : {&a.filter, &b.filter}) {
      f->predict(s.stamp_ns, s.distance_m, s.yaw_rate_radps);
      if (s.has_fix) {
        static_cast<void>(f->update(s.fix));
      }
    }
    const Pose2 pa = a.filter.estimate();
    const Pose2 pb = b.filter.estimate();
    ASSERT_EQ(pa.x_m, pb.x_m);
    ASSERT_EQ(pa.y_m, pb.y_m);
    ASSERT_EQ(pa.yaw_rad, pb.yaw_rad);
  }
}

TEST(ParticleFilter, PoseAtFollowsTheSmoothedPathInsideTheWindow) {
  DriveOptions options;
  options.duration_s = 100.0;
  const std::vector<Sample> samples = drive(options);
  FilterFixture fixture(behaviour_config());
  for (const Sample& s : samples) {
    fixture.filter.predict(s.stamp_ns, s.distance_m, s.yaw_rate_radps);
    if (s.has_fix) {
      static_cast<void>(fixture.filter.update(s.fix));
    }
  }
  // Inside the window: near the truth (the GPS error is 2 m); outside: false.
  for (const double t_s : {70.0, 85.3, 99.99}) {
    Pose2 pose;
    ASSERT_TRUE(fixture.filter.pose_at(static_cast<TimestampNs>(t_s * 1e9), pose)) << t_s;
    const Pose2& truth = samples[static_cast<std::size_t>(t_s * 100.0) - 1].truth;
    EXPECT_LT(std::hypot(pose.x_m - truth.x_m, pose.y_m - truth.y_m), 3.0) << t_s;
    EXPECT_LT(heading_error_rad(pose.yaw_rad, truth.yaw_rad), 0.1) << t_s;
  }
  Pose2 pose;
  EXPECT_FALSE(fixture.filter.pose_at(static_cast<TimestampNs>(200e9), pose));
}

TEST(LocalizeConfig, ValidateNamesWhatIsWrong) {
  EXPECT_EQ(validate(LocalizeConfig{}), "");
  LocalizeConfig config;
  config.particle_count = 1;
  EXPECT_NE(validate(config).find("particle_count"), std::string::npos);
  config = LocalizeConfig{};
  config.resample_effective_fraction = 1.5;
  EXPECT_NE(validate(config).find("resample_effective_fraction"), std::string::npos);
  config = LocalizeConfig{};
  config.user_range_error_m = 0.0;
  EXPECT_NE(validate(config).find("user_range_error_m"), std::string::npos);
}

}  // namespace
}  // namespace blockmap::localize
