// The localizer between the devices and the particle filter: integrated odometry to
// increments, the base's attitude and a GPS height on every pose.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/localize/localizer.hpp"
#include "synthetic_drive.hpp"

namespace blockmap::localize {
namespace {

// 1,000 particles: these tests are about the localizer, not the filter's accuracy, and run
// under QEMU too.
LocalizerConfig small_config() {
  LocalizerConfig config;
  config.filter.particle_count = 1000;
  return config;
}

struct Fixture {
  explicit Fixture(const LocalizerConfig& config = small_config())
      : arena(Localizer::arena_bytes(config)) {
    localizer.init(arena, config);
    arena.seal();
  }
  Arena arena;
  Localizer localizer;
};

constexpr double kPitchRad = 0.04;  // the base leaning forward
constexpr double kRollRad = -0.01;
constexpr double kGroundUpM = 12.0;  // the ground's height in the local frame

// Feeds the synthetic drive as the base and the receiver report it: integrated distance,
// IMU attitude, fixes with the antenna's height. `reset_at` (a sample index) makes the base
// restart its integrators there.
void feed(Localizer& localizer, const std::vector<synthetic::Sample>& samples,
          std::size_t reset_at = 0) {
  double integrated_m = 100.0;  // the base's counter need not start at zero
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const synthetic::Sample& s = samples[k];
    integrated_m = k == reset_at && reset_at > 0 ? 0.0 : integrated_m + s.distance_m;
    msg::OdometrySample odometry;
    odometry.header.stamp_ns = s.stamp_ns;
    odometry.fore_aft_distance_m = integrated_m;
    msg::ImuSample imu;
    imu.header.stamp_ns = s.stamp_ns;
    imu.yaw_rate_radps = s.yaw_rate_radps;
    imu.pitch_rad = kPitchRad;
    imu.roll_rad = kRollRad;
    localizer.on_base(odometry, imu);
    if (s.has_fix) {
      static_cast<void>(localizer.on_fix(s.fix, kGroundUpM + LocalizerConfig{}.antenna_height_m));
    }
  }
}

TEST(Localizer, TurnsIntegratedOdometryIntoPosesWithTheBasesAttitudeAndAHeight) {
  synthetic::DriveOptions options;
  options.duration_s = 120.0;
  const std::vector<synthetic::Sample> samples = synthetic::drive(options);
  Fixture fixture;
  feed(fixture.localizer, samples);
  std::vector<Pose3> poses(LocalizeConfig{}.history_steps);
  poses.resize(fixture.localizer.smoothed_window(poses));
  ASSERT_EQ(poses.size(), LocalizeConfig{}.history_steps);
  double sq = 0.0;
  std::size_t n = 0;
  for (const Pose3& p : poses) {
    EXPECT_NEAR(p.pitch_rad, kPitchRad, 1e-6);
    EXPECT_NEAR(p.roll_rad, kRollRad, 1e-6);
    EXPECT_NEAR(p.z_m, kGroundUpM, 1e-3);
    if (p.stamp_ns >= 60 * kNanosecondsPerSecond) {
      const Pose2& truth = samples[static_cast<std::size_t>(p.stamp_ns / 10'000'000) - 1].truth;
      sq += std::pow(p.x_m - truth.x_m, 2) + std::pow(p.y_m - truth.y_m, 2);
      ++n;
    }
  }
  EXPECT_LT(std::sqrt(sq / static_cast<double>(n)), 1.5);
  Pose3 at;
  ASSERT_TRUE(fixture.localizer.pose_at(100 * kNanosecondsPerSecond, at));
  EXPECT_NEAR(at.pitch_rad, kPitchRad, 1e-6);
  EXPECT_EQ(fixture.localizer.counters().odometry_jumps, 0u);
}

TEST(Localizer, AnIntegratorResetIsSkippedNotDriven) {
  synthetic::DriveOptions options;
  options.duration_s = 90.0;
  const std::vector<synthetic::Sample> samples = synthetic::drive(options);
  Fixture with_reset;
  feed(with_reset.localizer, samples, 5000);
  Fixture without;
  feed(without.localizer, samples);
  EXPECT_EQ(with_reset.localizer.counters().odometry_jumps, 1u);
  // One skipped 10 ms increment (1.2 cm) is all the reset costs.
  const Pose2 a = with_reset.localizer.filter().estimate();
  const Pose2 b = without.localizer.filter().estimate();
  EXPECT_LT(std::hypot(a.x_m - b.x_m, a.y_m - b.y_m), 0.5);
}

TEST(Localizer, ASampleOlderThanTheLastIsLeftOutAndCounted) {
  Fixture fixture;
  msg::OdometrySample odometry;
  msg::ImuSample imu;
  odometry.header.stamp_ns = 2'000'000'000;
  fixture.localizer.on_base(odometry, imu);
  odometry.header.stamp_ns = 1'000'000'000;
  odometry.fore_aft_distance_m = 5.0;
  fixture.localizer.on_base(odometry, imu);
  EXPECT_EQ(fixture.localizer.counters().stale_samples, 1u);
  EXPECT_EQ(fixture.localizer.counters().base_samples, 1u);
}

TEST(LocalizerConfig, ValidateNamesWhatIsWrong) {
  LocalizerConfig config;
  EXPECT_EQ(validate(config), "");
  config.max_speed_mps = 0.0;
  EXPECT_NE(validate(config).find("max_speed_mps"), std::string::npos);
  config = LocalizerConfig{};
  config.filter.particle_count = 1;
  EXPECT_NE(validate(config).find("particle_count"), std::string::npos);
}

}  // namespace
}  // namespace blockmap::localize
