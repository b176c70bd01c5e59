// The streaming map's pieces allocate nothing per scan: scan projection over a minute of
// scans at 75 Hz, the beam table rebuilt on a change of geometry included.
#include <gtest/gtest.h>

#include <array>
#include <numbers>

#include "blockmap/map/scan_projector.hpp"
#include "memory_assertions.hpp"

namespace blockmap::map {
namespace {

TEST(MapBudget, ProjectingScansAllocatesNothing) {
  ScanProjector projector(SensorMount{Eigen::Vector3d(0.3, 0.0, 1.0), std::numbers::pi / 2.0, 0.0,
                                      std::numbers::pi / 2.0},
                          ScanProjectorConfig{});
  msg::LaserScan scan;
  scan.beam_count = 361;
  scan.angle_increment_rad = std::numbers::pi / 360.0;
  scan.time_increment_s = 1.0 / 75.0 / 720.0;
  for (std::uint16_t i = 0; i < scan.beam_count; ++i) {
    scan.ranges_m[i] = 5.0f + 0.01f * static_cast<float>(i);
    scan.status[i] = msg::BeamStatus::kValid;
  }
  std::array<Eigen::Vector3f, msg::kMaxLaserBeams> points{};
  std::size_t projected = 0;
  const auto project_a_minute = [&] {
    for (int k = 0; k < 75 * 60; ++k) {
      scan.header.stamp_ns = TimestampNs{k} * 13'333'333;
      // Every tenth scan in another field: the beam table is rebuilt in place.
      scan.start_angle_rad = (k % 10 == 0 ? -1.0 : -0.5) * std::numbers::pi / 2.0;
      localize::Pose3 first;
      first.stamp_ns = ScanProjector::beam_stamp_ns(scan, 0);
      first.x_m = 0.01 * k;
      first.pitch_rad = 0.02;
      first.yaw_rad = 0.001 * k;
      localize::Pose3 last = first;
      last.stamp_ns = ScanProjector::last_beam_stamp_ns(scan);
      last.yaw_rad += 0.01;
      projected += projector.project(scan, first, last, points);
    }
  };
  EXPECT_NO_ALLOCATIONS(project_a_minute());
  EXPECT_EQ(projected, std::size_t{361} * 75 * 60);
  // Its whole state is the object itself: the beam table is a member array.
  EXPECT_LE(ScanProjector::memory_bytes(), std::size_t{32} * 1024);
}

}  // namespace
}  // namespace blockmap::map
