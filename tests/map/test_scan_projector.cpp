// Scan projection: beams through the mount and the robot's pose, motion during a scan, and
// every beam that is dropped counted by why.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "blockmap/map/scan_projector.hpp"
#include "test_units.hpp"

namespace blockmap::map {
namespace {

using blockmap::testing::kDeg;

localize::Pose3 pose(TimestampNs stamp_ns, double x_m, double y_m, double z_m, double roll_rad,
                     double pitch_rad, double yaw_rad) {
  return {stamp_ns, x_m, y_m, z_m, roll_rad, pitch_rad, yaw_rad};
}

// A scan of `count` beams from start_rad in steps of increment_rad, all valid at range_m.
msg::LaserScan scan_of(std::uint16_t count, double start_rad, double increment_rad, float range_m) {
  msg::LaserScan scan;
  scan.header.stamp_ns = 1'000'000'000;
  scan.beam_count = count;
  scan.start_angle_rad = start_rad;
  scan.angle_increment_rad = increment_rad;
  for (std::uint16_t i = 0; i < count; ++i) {
    scan.ranges_m[i] = range_m;
    scan.status[i] = msg::BeamStatus::kValid;
  }
  return scan;
}

void expect_near(const Eigen::Vector3f& actual, const Eigen::Vector3d& expected, double tol_m) {
  EXPECT_NEAR(actual.x(), expected.x(), tol_m);
  EXPECT_NEAR(actual.y(), expected.y(), tol_m);
  EXPECT_NEAR(actual.z(), expected.z(), tol_m);
}

TEST(ScanProjector, ABeamGoesThroughTheMountAndTheRobotsPose) {
  // A laser 0.2 m ahead of the axle and 0.5 m up, level; the robot at (10, 5) facing +y.
  const SensorMount mount{Eigen::Vector3d(0.2, 0.0, 0.5), 0.0, 0.0, 0.0};
  ScanProjector projector(mount, ScanProjectorConfig{});
  const msg::LaserScan scan = scan_of(1, 0.0, 0.0, 10.0f);
  const localize::Pose3 robot = pose(scan.header.stamp_ns, 10.0, 5.0, 0.0, 0.0, 0.0, 90.0 * kDeg);
  std::array<Eigen::Vector3f, 4> out{};
  ASSERT_EQ(projector.project(scan, robot, robot, out), 1u);
  expect_near(out[0], Eigen::Vector3d(10.0, 15.2, 0.5), 1e-5);
}

TEST(ScanProjector, APitchedRobotLooksDownAndARolledLaserScansUpright) {
  // Nose down by 5 deg (the RMP's positive pitch): a forward beam from 0.5 m up meets the
  // ground 0.5 / tan(5 deg) = 5.7 m ahead.
  ScanProjector level_laser(SensorMount{Eigen::Vector3d(0.0, 0.0, 0.5), 0.0, 0.0, 0.0}, {});
  const msg::LaserScan forward = scan_of(1, 0.0, 0.0, 10.0f);
  const double pitch = 5.0 * kDeg;
  const localize::Pose3 pitched = pose(forward.header.stamp_ns, 0.0, 0.0, 0.0, 0.0, pitch, 0.0);
  std::array<Eigen::Vector3f, 1> out{};
  ASSERT_EQ(level_laser.project(forward, pitched, pitched, out), 1u);
  // R_y(pitch) (10, 0, 0.5): (10 cos + 0.5 sin, 0, -10 sin + 0.5 cos)
  expect_near(out[0],
              Eigen::Vector3d(10.0 * std::cos(pitch) + 0.5 * std::sin(pitch), 0.0,
                              -10.0 * std::sin(pitch) + 0.5 * std::cos(pitch)),
              1e-5);
  EXPECT_LT(out[0].z(), 0.0);  // below the ground at 10 m: the beam reached it before
  // The paper's pushbroom laser: rolled 90 deg, its scan plane stands upright; the beam at
  // +90 deg in its own frame points straight up.
  ScanProjector upright(SensorMount{Eigen::Vector3d(0.0, 0.0, 1.0), 90.0 * kDeg, 0.0, 0.0}, {});
  const msg::LaserScan up = scan_of(1, 90.0 * kDeg, 0.0, 4.0f);
  const localize::Pose3 level = pose(up.header.stamp_ns, 1.0, 2.0, 0.0, 0.0, 0.0, 0.0);
  ASSERT_EQ(upright.project(up, level, level, out), 1u);
  expect_near(out[0], Eigen::Vector3d(1.0, 2.0, 5.0), 1e-5);
}

TEST(ScanProjector, TheRobotsTurnDuringAScanBendsItsBeamsBeamByBeam) {
  // Three beams straight ahead, 5 ms apart; the robot turns from 0 to 10 deg and moves 1 cm
  // in x between the first and the last. The middle beam was taken half way: at 5 deg.
  ScanProjector projector(SensorMount{}, {});
  msg::LaserScan scan = scan_of(3, 0.0, 0.0, 20.0f);
  scan.time_increment_s = 0.005;
  const TimestampNs first_ns = ScanProjector::beam_stamp_ns(scan, 0);
  const TimestampNs last_ns = ScanProjector::last_beam_stamp_ns(scan);
  EXPECT_EQ(last_ns - first_ns, 10'000'000);
  const localize::Pose3 first = pose(first_ns, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  const localize::Pose3 last = pose(last_ns, 0.01, 0.0, 0.0, 0.0, 0.0, 10.0 * kDeg);
  std::array<Eigen::Vector3f, 3> out{};
  ASSERT_EQ(projector.project(scan, first, last, out), 3u);
  expect_near(out[0], Eigen::Vector3d(20.0, 0.0, 0.0), 1e-5);
  expect_near(
      out[1],
      Eigen::Vector3d(0.005 + 20.0 * std::cos(5.0 * kDeg), 20.0 * std::sin(5.0 * kDeg), 0.0), 1e-5);
  expect_near(
      out[2],
      Eigen::Vector3d(0.01 + 20.0 * std::cos(10.0 * kDeg), 20.0 * std::sin(10.0 * kDeg), 0.0),
      1e-5);
  // Without beam timing every beam takes the first pose.
  scan.time_increment_s = 0.0;
  ASSERT_EQ(projector.project(scan, first, first, out), 3u);
  expect_near(out[2], Eigen::Vector3d(20.0, 0.0, 0.0), 1e-5);
}

TEST(ScanProjector, EveryDroppedBeamIsCountedByWhy) {
  ScanProjectorConfig config;
  config.min_range_m = 0.5;
  config.max_range_m = 30.0;
  ScanProjector projector(SensorMount{}, config);
  msg::LaserScan scan = scan_of(9, -0.1, 0.025, 10.0f);
  scan.status[0] = msg::BeamStatus::kNoReturn;
  scan.status[1] = msg::BeamStatus::kDazzled;
  scan.status[2] = msg::BeamStatus::kDeviceError;
  scan.status[3] = msg::BeamStatus::kTooClose;
  scan.ranges_m[4] = 0.2f;                                     // nearer than 0.5 m
  scan.ranges_m[5] = 35.0f;                                    // farther than 30 m
  scan.ranges_m[6] = std::numeric_limits<float>::quiet_NaN();  // marked valid
  const localize::Pose3 still = pose(scan.header.stamp_ns, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  std::array<Eigen::Vector3f, 1> out{};  // room for one of the two good beams
  EXPECT_EQ(projector.project(scan, still, still, out), 1u);
  const ProjectionCounters& c = projector.counters();
  EXPECT_EQ(c.scans, 1u);
  EXPECT_EQ(c.points, 1u);
  EXPECT_EQ(c.no_return, 1u);
  EXPECT_EQ(c.flagged, 3u);
  EXPECT_EQ(c.below_min_range, 1u);
  EXPECT_EQ(c.beyond_max_range, 1u);
  EXPECT_EQ(c.non_finite, 1u);
  EXPECT_EQ(c.output_full, 1u);
  // The one written is beam 7, at -0.1 + 7 * 0.025 rad.
  const double angle = -0.1 + 7 * 0.025;
  expect_near(out[0], Eigen::Vector3d(10.0 * std::cos(angle), 10.0 * std::sin(angle), 0.0), 1e-5);
}

TEST(ScanProjector, TheGroundFarFromTheLaserIsDroppedFromTheMapAndCounted) {
  // The RMP's level laser, 0.55 m above an axle 0.24 m above the ground, the robot nose down by
  // 2 deg: the beams at +-30 deg point down by cos(30 deg) * 2 deg and meet the ground 26 m
  // away, farther than 8 m; the beams to the side stay level (0.79 m up) and meet walls 10 m to
  // the right and 6 m to the left.
  ScanProjectorConfig config;
  config.far_ground_range_m = 8.0;
  config.ground_band_m = 0.4;
  config.axle_height_m = 0.24;
  const SensorMount mount{Eigen::Vector3d(0.0, 0.0, 0.55), 0.0, 0.0, 0.0};
  ScanProjector projector(mount, config);
  const double pitch = 2.0 * kDeg;
  const double laser_height_m = 0.24 + 0.55 * std::cos(pitch);  // it tilts about the axle
  msg::LaserScan scan =
      scan_of(4, -90.0 * kDeg, 60.0 * kDeg,
              static_cast<float>(laser_height_m / (std::cos(30.0 * kDeg) * std::sin(pitch))));
  scan.ranges_m[0] = 10.0f;  // -90 deg, right
  scan.ranges_m[3] = 6.0f;   // +90 deg, left
  const localize::Pose3 robot = pose(scan.header.stamp_ns, 5.0, 0.0, 0.24, 0.0, pitch, 0.0);
  std::array<Eigen::Vector3f, 4> out{};
  ASSERT_EQ(projector.project(scan, robot, robot, out), 4u);  // every point, for the matcher
  EXPECT_NEAR(out[1].z(), 0.0f, 1e-4);                        // on the ground
  ASSERT_EQ(projector.drop_far_ground(robot, out), 2u);
  EXPECT_EQ(projector.counters().far_ground, 2u);
  EXPECT_NEAR(out[0].y(), -10.0f, 1e-4);  // in their order
  EXPECT_NEAR(out[1].y(), 6.0f, 1e-4);

  // The ground within 8 m is kept: at 10 deg nose down the forward beam meets it 4.4 m ahead.
  const double steep = 10.0 * kDeg;
  const double steep_height_m = 0.24 + 0.55 * std::cos(steep);
  const msg::LaserScan near =
      scan_of(1, 0.0, 0.0, static_cast<float>(steep_height_m / std::sin(steep)));
  const localize::Pose3 nose_down = pose(near.header.stamp_ns, 5.0, 0.0, 0.24, 0.0, steep, 0.0);
  ASSERT_EQ(projector.project(near, nose_down, nose_down, out), 1u);
  EXPECT_NEAR(out[0].z(), 0.0f, 1e-4);
  EXPECT_EQ(projector.drop_far_ground(nose_down, std::span(out).first(1)), 1u);
  EXPECT_EQ(projector.counters().far_ground, 2u);

  // Off (the default, which knows no ground): every point stays.
  ScanProjector keeps_all(mount, ScanProjectorConfig{});
  ASSERT_EQ(keeps_all.project(scan, robot, robot, out), 4u);
  EXPECT_EQ(keeps_all.drop_far_ground(robot, out), 4u);
  EXPECT_EQ(keeps_all.counters().far_ground, 0u);
}

TEST(ScanProjector, ANewScanGeometryIsTakenUpAtOnce) {
  // A scanner reconfigured between scans (another field or resolution): the beam table
  // follows the scan, not the first one seen.
  ScanProjector projector(SensorMount{}, {});
  const localize::Pose3 still = pose(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  std::array<Eigen::Vector3f, 2> out{};
  ASSERT_EQ(projector.project(scan_of(2, 0.0, 90.0 * kDeg, 1.0f), still, still, out), 2u);
  expect_near(out[1], Eigen::Vector3d(0.0, 1.0, 0.0), 1e-6);
  ASSERT_EQ(projector.project(scan_of(2, 0.0, -90.0 * kDeg, 1.0f), still, still, out), 2u);
  expect_near(out[1], Eigen::Vector3d(0.0, -1.0, 0.0), 1e-6);
}

}  // namespace
}  // namespace blockmap::map
