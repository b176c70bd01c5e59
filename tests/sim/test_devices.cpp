// Devices on simulated ports, Given/When/Then: the same decoders the robot uses, fed the same
// bytes through the simulated ports, with faults injected.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <set>
#include <tuple>
#include <vector>

#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/sim/loopback_can_bus.hpp"
#include "blockmap/hal/sim/scripted_byte_stream.hpp"
#include "test_data.hpp"

namespace blockmap::hal::devices {
namespace {

using sim::ManualClock;

// (time of day, latitude, longitude) of every GGA in a log, decoded in one piece.
std::vector<std::tuple<std::int32_t, double, double>> gga_positions(
    std::span<const std::uint8_t> log) {
  protocol::nmea::Decoder decoder;
  std::vector<std::tuple<std::int32_t, double, double>> positions;
  while (!log.empty()) {
    const auto step = decoder.push(log, 0);
    log = log.subspan(step.consumed);
    if (step.sentence != nullptr && step.sentence->type == protocol::nmea::SentenceType::kGga) {
      const msg::GpsFix& fix = step.sentence->fix;
      positions.emplace_back(fix.utc_milliseconds_of_day, fix.latitude_deg, fix.longitude_deg);
    }
  }
  return positions;
}

struct GpsRig {
  explicit GpsRig(std::span<const std::uint8_t> log, const sim::ScriptedStreamConfig& stream_config)
      : stream(log, clock, stream_config, written), receiver(stream, queue, GpsReceiverConfig{}) {}
  // Polls until the stream ends, draining the queue like the pipeline thread would.
  IoStatus run(std::vector<msg::GpsFix>& fixes) {
    IoStatus status = IoStatus::kOk;
    while ((status = receiver.poll(0)) == IoStatus::kOk) {
      for (msg::GpsFix fix; queue.try_pop(fix);) fixes.push_back(fix);
    }
    for (msg::GpsFix fix; queue.try_pop(fix);) fixes.push_back(fix);
    return status;
  }
  ManualClock clock;
  std::array<std::uint8_t, 64> written{};
  sim::ScriptedByteStream stream;
  SpscQueue<msg::GpsFix, 16> queue;
  GpsReceiver receiver;
};

TEST(GpsReceiver, PublishesOneFixPerGgaFromAChunkedStream) {
  // Given a real Trimble RTK log replayed at 9600 baud in random chunks
  const auto log = testing::read_bytes(testing::project_data("nmea/gpsd_nmea-fuzzy-cases.log"));
  const auto expected = gga_positions(log);
  ASSERT_GT(expected.size(), 10u);
  sim::ScriptedStreamConfig config;
  config.baud = 9600;
  GpsRig rig(log, config);
  // When the receiver is polled until the line closes
  std::vector<msg::GpsFix> fixes;
  EXPECT_EQ(rig.run(fixes), IoStatus::kClosed);
  // Then each GGA became exactly one fix, in order, stamped with the simulated arrival time
  ASSERT_EQ(fixes.size(), expected.size());
  TimestampNs previous_ns = -1;
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    EXPECT_EQ(fixes[i].utc_milliseconds_of_day, std::get<0>(expected[i]));
    EXPECT_DOUBLE_EQ(fixes[i].latitude_deg, std::get<1>(expected[i]));
    EXPECT_DOUBLE_EQ(fixes[i].longitude_deg, std::get<2>(expected[i]));
    EXPECT_GT(fixes[i].header.stamp_ns, previous_ns);
    previous_ns = fixes[i].header.stamp_ns;
  }
  EXPECT_EQ(rig.receiver.fixes_rejected(), 0u);
}

TEST(GpsReceiver, MergesSpeedOfAnEarlierRmcOfTheSameEpoch) {
  const std::string log =
      "$GNRMC,081411.000,A,5541.1955,N,03737.2872,E,0.60,301.29,260514,,,A*74\r\n"
      "$GPGGA,081411.000,5541.1956,N,03737.2877,E,1,5,4.87,66.2,M,14.5,M,,*69\r\n"
      "$GPGGA,081412.000,5541.1956,N,03737.2877,E,1,5,4.87,66.2,M,14.5,M,,*6A\r\n";
  const std::vector<std::uint8_t> bytes(log.begin(), log.end());
  GpsRig rig(bytes, sim::ScriptedStreamConfig{});
  std::vector<msg::GpsFix> fixes;
  (void)rig.run(fixes);
  // The RMC is a fix of its own only until the first GGA shows the receiver sends them.
  ASSERT_EQ(fixes.size(), 3u);
  EXPECT_EQ(fixes[0].utc_milliseconds_of_day, fixes[1].utc_milliseconds_of_day);
  EXPECT_TRUE(fixes[1].has_velocity);
  EXPECT_NEAR(fixes[1].speed_mps, 0.60 * 1852.0 / 3600.0, 1e-9);
  EXPECT_TRUE(fixes[1].has_date);
  EXPECT_TRUE(fixes[1].has_altitude) << "and the GGA's own fields";
  EXPECT_FALSE(fixes[2].has_velocity) << "a later epoch does not inherit an old speed";
}

TEST(GpsReceiver, PublishesRmcWhenTheReceiverSendsNoGga) {
  const std::string log =
      "$GNRMC,081411.000,A,5541.1955,N,03737.2872,E,0.60,301.29,260514,,,A*74\r\n"
      "$GPRMC,081836,A,3751.65,S,14507.36,E,000.0,360.0,130998,011.3,E*62\r\n";
  const std::vector<std::uint8_t> bytes(log.begin(), log.end());
  GpsRig rig(bytes, sim::ScriptedStreamConfig{});
  std::vector<msg::GpsFix> fixes;
  (void)rig.run(fixes);
  ASSERT_EQ(fixes.size(), 2u);
  EXPECT_NEAR(fixes[1].latitude_deg, -37.86083333333333, 1e-12);
}

TEST(GpsReceiver, DamagedLineYieldsOnlyTrueFixesAndCountsTheRest) {
  // Given the same log on a noisy line: flipped bits, lost bytes, bursts of garbage
  const auto log = testing::read_bytes(testing::project_data("nmea/gpsd_bu353-glonass.log"));
  const auto expected = gga_positions(log);
  sim::ScriptedStreamConfig config;
  config.seed = 11;
  config.bit_flip_probability = 0.001;
  config.drop_probability = 0.001;
  config.garbage_probability = 0.05;
  GpsRig rig(log, config);
  std::vector<msg::GpsFix> fixes;
  (void)rig.run(fixes);
  // Then every published fix is one the receiver really sent, most still get through, and the
  // decoder's counters account for the damage
  const std::set<std::tuple<std::int32_t, double, double>> truth(expected.begin(), expected.end());
  for (const msg::GpsFix& fix : fixes) {
    EXPECT_TRUE(truth.count({fix.utc_milliseconds_of_day, fix.latitude_deg, fix.longitude_deg}))
        << "a damaged sentence became a fix";
  }
  EXPECT_GT(fixes.size(), expected.size() / 2);
  EXPECT_LT(fixes.size(), expected.size());
  const auto& drops = rig.receiver.decoder().drops();
  EXPECT_GT(drops.value(protocol::nmea::DropReason::kBadChecksum) +
                drops.value(protocol::nmea::DropReason::kTruncated),
            0u);
}

TEST(GpsReceiver, FullQueueRejectsAndCountsInsteadOfBlocking) {
  const auto log = testing::read_bytes(testing::project_data("nmea/gpsd_nmea-fuzzy-cases.log"));
  const std::size_t ggas = gga_positions(log).size();
  ManualClock clock;
  std::array<std::uint8_t, 8> written{};
  sim::ScriptedByteStream stream(log, clock, sim::ScriptedStreamConfig{}, written);
  SpscQueue<msg::GpsFix, 4> queue;  // nobody drains it
  GpsReceiver receiver(stream, queue, GpsReceiverConfig{});
  while (receiver.poll(0) == IoStatus::kOk) {
  }
  EXPECT_EQ(receiver.fixes_published(), 4u);
  EXPECT_EQ(receiver.fixes_rejected(), ggas - 4);
}

// A simulated Segway base: one status group every 10 ms, as the real one sends.
struct SegwayRig {
  explicit SegwayRig(const sim::LoopbackCanConfig& bus_config)
      : bus(clock, bus_config, pending, sent), base(bus, odometry, imu, SegwayBaseConfig{}) {}

  void send_group(double fore_aft_m, double yaw_rate_radps = 0.0) {
    protocol::segway_rmp::StatusCycle cycle;
    cycle.odometry.fore_aft_distance_m = fore_aft_m;
    cycle.imu.yaw_rate_radps = yaw_rate_radps;
    cycle.odometry.servo_frame_count = servo_frames++;
    cycle.imu.pitch_rad = 0.05;
    const auto frames = protocol::segway_rmp::encode_status(cycle, protocol::segway_rmp::Config{});
    for (const CanFrame& frame : frames.frames) {
      (void)bus.inject(frame);
    }
    CanFrame heartbeat;  // the UI's heartbeat shares the bus
    heartbeat.id = 0x688;
    heartbeat.dlc = 8;
    (void)bus.inject(heartbeat);
  }

  ManualClock clock;
  std::array<sim::PendingCanFrame, 256> pending{};
  std::array<CanFrame, 4> sent{};
  sim::LoopbackCanBus bus;
  SpscQueue<msg::OdometrySample, 256> odometry;
  SpscQueue<msg::ImuSample, 256> imu;
  SegwayBase base;
  std::uint16_t servo_frames = 0;
};

TEST(SegwayBase, PublishesOdometryAndImuPerStatusGroup) {
  // Given a base that drives 1 cm per 10 ms group for one second
  sim::LoopbackCanConfig config;
  config.delay_ns = 200'000;
  SegwayRig rig(config);
  ASSERT_EQ(rig.base.install_filters(), IoStatus::kOk);
  for (int group = 0; group < 100; ++group) {
    rig.send_group(0.01 * group);
    (void)rig.clock.advance_ns(10'000'000);
    // When the reader polls once per group
    EXPECT_EQ(rig.base.poll(0), IoStatus::kOk);
  }
  // Then every group became one odometry and one IMU sample, stamped at arrival
  ASSERT_EQ(rig.odometry.size_approx(), 100u);
  msg::OdometrySample sample;
  msg::ImuSample attitude;
  for (int group = 0; group < 100; ++group) {
    ASSERT_TRUE(rig.odometry.try_pop(sample));
    ASSERT_TRUE(rig.imu.try_pop(attitude));
    EXPECT_NEAR(sample.fore_aft_distance_m, 0.01 * group, 1.0 / 33215.0);
    EXPECT_EQ(sample.header.stamp_ns, attitude.header.stamp_ns);
    EXPECT_EQ(sample.header.stamp_ns, 10'000'000LL * group + 200'000) << "sent + bus delay";
    EXPECT_NEAR(attitude.pitch_rad, 0.05, 0.003);
  }
  EXPECT_EQ(rig.base.decoder().drops().value(protocol::segway_rmp::DropReason::kForeignId), 0u)
      << "the filters keep the UI heartbeat off the socket";
}

TEST(SegwayBase, LostFramesCostOnlyTheirGroupAndBusOffIsReported) {
  sim::LoopbackCanConfig config;
  config.seed = 3;
  config.drop_probability = 0.02;
  config.duplicate_probability = 0.02;
  SegwayRig rig(config);
  (void)rig.base.install_filters();
  for (int group = 0; group < 200; ++group) {
    rig.send_group(0.01 * group);
    (void)rig.base.poll(0);
  }
  const auto& drops = rig.base.decoder().drops();
  const std::uint64_t incomplete = drops.value(protocol::segway_rmp::DropReason::kIncompleteCycle);
  EXPECT_GT(incomplete, 0u);
  EXPECT_GT(drops.value(protocol::segway_rmp::DropReason::kDuplicate), 0u);
  EXPECT_LE(rig.base.samples_published() + incomplete, 200u);
  EXPECT_GE(rig.base.samples_published() + incomplete, 190u) << "only a lost 0x407 hides a group";
  rig.bus.set_bus_off(true);
  EXPECT_EQ(rig.base.poll(0), IoStatus::kDeviceLost);
}

TEST(SegwayBase, AGroupNoRmpCouldSendIsNotPublished) {
  // Given a base driving 1 cm per group whose log has two damaged groups: a yaw rate of 100
  // rad/s, and a distance 3 m on in 10 ms
  SegwayRig rig(sim::LoopbackCanConfig{});
  (void)rig.base.install_filters();
  std::vector<double> published;
  for (int group = 0; group < 20; ++group) {
    const double fore_aft_m = 0.01 * group + (group == 12 ? 3.0 : 0.0);
    rig.send_group(fore_aft_m, group == 5 ? 100.0 : 0.1);
    (void)rig.clock.advance_ns(10'000'000);
    (void)rig.base.poll(0);
    for (msg::OdometrySample sample; rig.odometry.try_pop(sample);) {
      published.push_back(sample.fore_aft_distance_m);
    }
  }
  // Then those two are left out and counted, and the rest published as they came
  EXPECT_EQ(rig.base.groups_implausible(), 2u);
  ASSERT_EQ(published.size(), 18u);
  EXPECT_NEAR(published[5], 0.06, 1e-4);
  EXPECT_NEAR(published[11], 0.13, 1e-4);
}

TEST(SegwayBase, AfterThreeRefusalsInARowTheNextGroupIsTheNewStart) {
  // Given a base whose integrators reset (the distance drops from 5 m to 0)
  SegwayRig rig(sim::LoopbackCanConfig{});
  (void)rig.base.install_filters();
  std::size_t published = 0;
  for (int group = 0; group < 20; ++group) {
    rig.send_group(group < 10 ? 5.0 + 0.01 * group : 0.01 * (group - 10));
    (void)rig.clock.advance_ns(10'000'000);
    (void)rig.base.poll(0);
    for (msg::OdometrySample sample; rig.odometry.try_pop(sample);) {
      ++published;
    }
  }
  // Then three groups are refused and the base goes on from the fourth
  EXPECT_EQ(rig.base.groups_implausible(), 3u);
  EXPECT_EQ(published, 17u);
}

}  // namespace
}  // namespace blockmap::hal::devices
