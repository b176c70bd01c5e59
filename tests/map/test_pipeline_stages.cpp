// The mapper's stages on their own: the reorder buffer, the scan queue, the given poses and the
// lasers' own scan planes, each with the inputs that decide what it gives.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/map/scan_projector.hpp"
#include "blockmap/pipeline/reorder_buffer.hpp"
#include "blockmap/pipeline/scan_planes.hpp"
#include "blockmap/pipeline/scan_poses.hpp"
#include "blockmap/pipeline/scan_queue.hpp"

namespace blockmap::pipeline {
namespace {

constexpr TimestampNs kMs = 1'000'000;

TimedMessage base_at(TimestampNs stamp_ns) {
  TimedMessage message;
  message.kind = TimedMessage::Kind::kBase;
  message.stamp_ns = stamp_ns;
  return message;
}

// A reorder buffer and the stamps it released, in order.
struct Reordering {
  Reordering(std::size_t capacity, double window_s) : arena(1 << 20) {
    buffer.init(arena, capacity, window_s);
  }
  ReorderBuffer::Outcome add(TimestampNs stamp_ns) {
    return buffer.add(base_at(stamp_ns), [this](const TimedMessage& m) { keep(m); });
  }
  void release_due(bool all) {
    buffer.release_due(all, [this](const TimedMessage& m) { keep(m); });
  }
  void keep(const TimedMessage& message) { released.push_back(message.stamp_ns); }

  Arena arena;
  ReorderBuffer buffer;
  std::vector<TimestampNs> released;
};

TEST(ReorderBuffer, ReleasesInTimeOrderWhatIsOlderThanTheWindow) {
  Reordering reordering(8, 0.05);
  for (const TimestampNs stamp_ns : {30 * kMs, 10 * kMs, 20 * kMs, 90 * kMs}) {
    EXPECT_EQ(reordering.add(stamp_ns), ReorderBuffer::Outcome::kQueued);
  }
  reordering.release_due(false);
  EXPECT_EQ(reordering.released, (std::vector<TimestampNs>{10 * kMs, 20 * kMs, 30 * kMs}))
      << "the newest, 90 ms, is not 50 ms older than itself";
  EXPECT_EQ(reordering.buffer.size(), 1u);
  reordering.release_due(true);
  EXPECT_EQ(reordering.released.back(), 90 * kMs) << "at the end everything goes";
}

TEST(ReorderBuffer, AMessageOlderThanOneReleasedIsLate) {
  Reordering reordering(8, 0.0);
  ASSERT_EQ(reordering.add(20 * kMs), ReorderBuffer::Outcome::kQueued);
  reordering.release_due(false);
  EXPECT_EQ(reordering.add(10 * kMs), ReorderBuffer::Outcome::kLate);
  EXPECT_EQ(reordering.add(20 * kMs), ReorderBuffer::Outcome::kQueued)
      << "the same stamp as the last released is not late";
  EXPECT_EQ(reordering.released, (std::vector<TimestampNs>{20 * kMs}));
}

TEST(ReorderBuffer, AFullBufferReleasesItsOldestEarly) {
  Reordering reordering(2, 10.0);
  EXPECT_EQ(reordering.add(2 * kMs), ReorderBuffer::Outcome::kQueued);
  EXPECT_EQ(reordering.add(1 * kMs), ReorderBuffer::Outcome::kQueued);
  EXPECT_EQ(reordering.add(3 * kMs), ReorderBuffer::Outcome::kForcedEarly);
  EXPECT_EQ(reordering.released, (std::vector<TimestampNs>{1 * kMs}));
  EXPECT_EQ(reordering.buffer.size(), 2u);
}

msg::LaserScan scan_at(TimestampNs stamp_ns, std::size_t beams) {
  msg::LaserScan scan;
  scan.header.stamp_ns = stamp_ns;
  scan.time_increment_s = 1e-4;
  scan.range_max_m = 80.0;
  scan.beam_count = static_cast<std::uint16_t>(beams);
  for (std::size_t i = 0; i < beams; ++i) {
    scan.ranges_m[i] = 10.0f;
    scan.status[i] = msg::BeamStatus::kValid;
  }
  return scan;
}

// A scan queue with its own arena.
struct Queue {
  Queue(std::size_t slots, std::size_t max_beams) : arena(1 << 20) {
    queue.init(arena, slots, max_beams);
  }
  Arena arena;
  ScanQueue queue;
};

TEST(ScanQueue, RefusesAScanWhenFullOrTooLong) {
  Queue fixture(2, 100);
  ScanQueue& queue = fixture.queue;
  EXPECT_EQ(queue.push(0, scan_at(1 * kMs, 101)), ScanQueue::Outcome::kTooManyBeams);
  EXPECT_EQ(queue.push(0, scan_at(1 * kMs, 100)), ScanQueue::Outcome::kQueued);
  EXPECT_EQ(queue.push(1, scan_at(2 * kMs, 100)), ScanQueue::Outcome::kQueued);
  EXPECT_EQ(queue.push(0, scan_at(3 * kMs, 100)), ScanQueue::Outcome::kFull);
  EXPECT_EQ(queue.size(), 2u);
}

TEST(ScanQueue, GivesTheOldestScanThePosesCover) {
  Queue fixture(4, 100);
  ScanQueue& queue = fixture.queue;
  // Arrival order is not time order: laser 1's scan came last but is the oldest.
  const std::array<std::pair<std::size_t, TimestampNs>, 3> arrivals{
      {{0, 20 * kMs}, {0, 40 * kMs}, {1, 10 * kMs}}};
  for (const auto& [laser, stamp_ns] : arrivals) {
    ASSERT_EQ(queue.push(laser, scan_at(stamp_ns, 100)), ScanQueue::Outcome::kQueued);
  }
  TimestampNs waiting_ns = 0;
  // Each scan's last beam is 99 x 0.1 ms = 9.9 ms after its first; messages come within
  // 50 ms of time order.
  constexpr TimestampNs kWindowNs = 50 * kMs;
  const std::ptrdiff_t ready = queue.next_ready(true, 31 * kMs, kWindowNs, false, waiting_ns);
  ASSERT_EQ(ready, 2);
  EXPECT_EQ(queue.laser(2), 1u);
  EXPECT_EQ(waiting_ns, 40 * kMs) << "the scan at 40 ms waits";
  EXPECT_EQ(queue.expand(2).header.stamp_ns, 10 * kMs);
  queue.remove(2);
  EXPECT_EQ(queue.next_ready(true, 31 * kMs, kWindowNs, false, waiting_ns), 0);
  EXPECT_EQ(queue.next_ready(false, 0, kWindowNs, false, waiting_ns), -1)
      << "no poses, nothing ready";
  EXPECT_EQ(queue.next_ready(false, 0, kWindowNs, true, waiting_ns), 0) << "at the end, every scan";
}

TEST(ScanQueue, ScansBeforeABoundLeaveAndTheirSlotsAreFreeAgain) {
  Queue fixture(3, 10);
  ScanQueue& queue = fixture.queue;
  for (const TimestampNs stamp_ns : {5 * kMs, 1 * kMs, 9 * kMs}) {
    ASSERT_EQ(queue.push(0, scan_at(stamp_ns, 10)), ScanQueue::Outcome::kQueued);
  }
  EXPECT_EQ(queue.oldest_stamp(), 1 * kMs);
  EXPECT_EQ(queue.remove_before(6 * kMs), 2u);
  EXPECT_EQ(queue.size(), 1u);
  EXPECT_EQ(queue.header(0).header.stamp_ns, 9 * kMs);
  EXPECT_EQ(queue.push(0, scan_at(12 * kMs, 10)), ScanQueue::Outcome::kQueued);
  EXPECT_EQ(queue.push(0, scan_at(13 * kMs, 10)), ScanQueue::Outcome::kQueued);
  EXPECT_EQ(queue.size(), 3u);
}

localize::Pose3 pose_at(TimestampNs stamp_ns, double x_m, double yaw_rad) {
  localize::Pose3 pose;
  pose.stamp_ns = stamp_ns;
  pose.x_m = x_m;
  pose.yaw_rad = yaw_rad;
  return pose;
}

// Given poses (a simulation's truth, a survey), with the filter beside them as on the robot.
struct GivenPoses {
  GivenPoses() : arena(64 << 20) {
    poses.init(arena, PoseSource::kExternal, localize::LocalizerConfig{}, 4);
  }
  Arena arena;
  ScanPoses poses;
};

TEST(ScanPoses, GivenPosesAreInterpolatedAcrossTheTurnAtPi) {
  GivenPoses given;
  ScanPoses& poses = given.poses;
  TimestampNs horizon_ns = 0;
  EXPECT_FALSE(poses.horizon(horizon_ns));
  poses.on_pose(pose_at(0, 0.0, std::numbers::pi - 0.1));
  poses.on_pose(pose_at(100 * kMs, 1.0, -std::numbers::pi + 0.1));
  ASSERT_TRUE(poses.horizon(horizon_ns));
  EXPECT_EQ(horizon_ns, 100 * kMs);
  localize::Pose3 middle;
  ASSERT_TRUE(poses.at(50 * kMs, middle));
  EXPECT_DOUBLE_EQ(middle.x_m, 0.5);
  EXPECT_NEAR(std::abs(middle.yaw_rad), std::numbers::pi, 1e-12) << "through pi, not zero";
  EXPECT_FALSE(poses.at(150 * kMs, middle)) << "past the newest pose";
}

TEST(ScanPoses, TheFirstGivenPoseIsNoOlderThanTheLastMessageIn) {
  GivenPoses given;
  TimestampNs bound_ns = 0;
  EXPECT_FALSE(given.poses.first_pose_bound(bound_ns));
  msg::OdometrySample odometry;
  odometry.header.stamp_ns = 70 * kMs;
  given.poses.on_base(odometry, msg::ImuSample{});
  ASSERT_TRUE(given.poses.first_pose_bound(bound_ns));
  EXPECT_EQ(bound_ns, 70 * kMs);
}

TEST(ScanPlanes, ALaserMovingInItsScanPlaneLeavesItOutAndOneSweepingAcrossDoesNot) {
  ScanPlanes scan_planes;
  scan_planes.init(10.0, 0.5, 0.5);
  // Laser 0 level (its scan plane horizontal), laser 1 pitched up to scan across the way.
  const map::ScanProjector level(map::SensorMount{}, map::ScanProjectorConfig{});
  map::SensorMount across_mount;
  across_mount.pitch_rad = std::numbers::pi / 2;
  const map::ScanProjector across(across_mount, map::ScanProjectorConfig{});
  for (int step = 0; step < 10; ++step) {
    const localize::Pose3 pose =
        pose_at(TimestampNs{step} * 100 * kMs, static_cast<double>(step), 0.0);
    scan_planes.record(0, level, pose);
    scan_planes.record(1, across, pose);
  }
  const std::span<const planes::PlaneExclusion> exclusions = scan_planes.exclusions(2);
  ASSERT_EQ(exclusions.size(), 1u) << "only the level laser lays a sheet";
  EXPECT_NEAR(std::abs(exclusions[0].normal.z()), 1.0, 1e-9);
  EXPECT_EQ(exclusions[0].origins_m.size(), 9u) << "every 0.5 m moved, from the second scan";
}

}  // namespace
}  // namespace blockmap::pipeline
