// Segway RMP codec and candump log lines: golden frames from libsegwayrmp's tests and a real
// Orca bus capture, status-group assembly, encoders (docs/protocols.md section 1).
#include "blockmap/hal/protocol/segway_rmp.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "blockmap/hal/protocol/candump.hpp"
#include "test_data.hpp"
#include "test_units.hpp"

namespace blockmap::hal::protocol::segway_rmp {
namespace {

using blockmap::testing::kDeg;

std::vector<CanFrame> read_id_bytes_file(const std::filesystem::path& path) {
  std::istringstream text(blockmap::testing::read_text(path));
  std::vector<CanFrame> frames;
  std::string line;
  while (std::getline(text, line)) {
    candump::Record record;
    if (candump::parse_id_bytes_line(line, record) == candump::ParseError::kNone) {
      frames.push_back(record.frame);
    }
  }
  return frames;
}

CanFrame frame_of(std::string_view candump_frame) {
  candump::Record record;
  const std::string line = std::string("(0.000000) can0 ") + std::string(candump_frame);
  EXPECT_EQ(candump::parse_line(line, record), candump::ParseError::kNone) << candump_frame;
  return record.frame;
}

std::string text_of(const CanFrame& frame) {
  candump::Record record;
  record.interface = {'c', 'a', 'n', '0'};
  record.frame = frame;
  char line[64];
  const std::size_t length = candump::format_line(record, line);
  EXPECT_GT(length, 0u);
  return std::string(line, length).substr(std::string("(0.000000) can0 ").size());
}

// --- golden frames: the values libsegwayrmp's unit tests assert, within their tolerances

TEST(SegwayRmp, LibsegwayrmpTestFramesDecodeToTheAssertedValues) {
  const auto frames = read_id_bytes_file(
      blockmap::testing::project_data("segway_rmp/libsegwayrmp_unit_test_frames.txt"));
  ASSERT_EQ(frames.size(), 6u);
  Decoder decoder;
  for (const CanFrame& frame : frames) {
    EXPECT_EQ(decoder.push(frame, 0).kind, Decoder::FrameKind::kStatus);
  }
  const StatusCycle& v = decoder.latest();
  EXPECT_NEAR(v.imu.pitch_rad, -0.897 * kDeg, 0.128 * kDeg);
  EXPECT_NEAR(v.imu.pitch_rate_radps, 1.923 * kDeg, 0.128 * kDeg);
  EXPECT_NEAR(v.imu.roll_rad, -0.128 * kDeg, 0.128 * kDeg);
  EXPECT_NEAR(v.imu.roll_rate_radps, 1.154 * kDeg, 0.128 * kDeg);
  EXPECT_NEAR(v.odometry.left_wheel_velocity_mps, 0.0361, 0.003);
  EXPECT_NEAR(v.odometry.right_wheel_velocity_mps, -0.0422, 0.003);
  EXPECT_NEAR(v.imu.yaw_rate_radps, 9.6154 * kDeg, 0.128 * kDeg);
  EXPECT_NEAR(v.odometry.servo_frame_count * 0.01, 63.56, 0.01);
  EXPECT_NEAR(v.odometry.left_wheel_distance_m, -0.0152341, 0.00003);
  EXPECT_NEAR(v.odometry.right_wheel_distance_m, 0.0023784, 0.00003);
  EXPECT_NEAR(v.odometry.fore_aft_distance_m, -0.0300768, 0.00003);
  EXPECT_NEAR(v.odometry.yaw_displacement_rad, -0.268452 * kDeg, 0.00001 * kDeg);
  EXPECT_NEAR(v.left_motor_torque_nm, -0.006399, 0.0009);
  EXPECT_NEAR(v.right_motor_torque_nm, 0.152651, 0.0009);
  EXPECT_NEAR(v.status.ui_battery_v, 9.325, 1e-9);
  EXPECT_NEAR(v.status.powerbase_battery_v, 78.0, 0.25);
  EXPECT_EQ(v.status.operational_mode, 1);
  EXPECT_EQ(decoder.cycles_decoded(), 0u) << "no 0x407 closed the group";
}

TEST(SegwayRmp, Rmp100ScaleFactorsDiffer) {
  const ScaleFactors rmp100 = scale_factors(Model::kRmp100);
  const ScaleFactors rmp400 = scale_factors(Model::kRmp400);
  EXPECT_DOUBLE_EQ(rmp100.counts_per_mps, 401.0);
  EXPECT_DOUBLE_EQ(rmp100.counts_per_m, 40181.0);
  EXPECT_DOUBLE_EQ(rmp400.counts_per_rev, 112644.0);
  Config config;
  config.model = Model::kRmp100;
  Decoder decoder(config);
  (void)decoder.push(frame_of("403#9CF50000FFFF6383"), 0);  // +/-40181 counts
  EXPECT_NEAR(decoder.latest().odometry.left_wheel_distance_m, 1.0, 1e-4);
}

TEST(SegwayRmp, RealOrcaCaptureAssemblesTheTwoCompleteGroups) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(path, "vectors/segway_rmp/orca_can_capture_2007-03-27.txt");
  const auto frames = read_id_bytes_file(path);
  ASSERT_EQ(frames.size(), 41u);
  Decoder decoder;
  std::vector<StatusCycle> cycles;
  TimestampNs stamp_ns = 0;
  for (const CanFrame& frame : frames) {
    stamp_ns += 1'000'000;
    const Decoder::Step step = decoder.push(frame, stamp_ns);
    if (step.cycle != nullptr) {
      cycles.push_back(*step.cycle);
    }
  }
  ASSERT_EQ(cycles.size(), 2u);
  EXPECT_EQ(decoder.drops().value(DropReason::kIncompleteCycle), 1u) << "the log starts mid-group";
  EXPECT_GT(decoder.drops().value(DropReason::kForeignId), 0u) << "UI frames 0x412/0x414/0x688";
  const StatusCycle& first = cycles.front();
  EXPECT_EQ(first.status.operational_mode, 1) << "tractor";
  EXPECT_NEAR(first.status.powerbase_battery_v, 76.0, 1e-9);
  EXPECT_TRUE(first.status.motors_enabled) << "0x680 word 1 bit 0x0080";
  EXPECT_EQ(first.odometry.header.stamp_ns + 10'000'000, cycles.back().odometry.header.stamp_ns)
      << "a group is stamped with its 0x400 frame";
  // The servo frame counter advances by one per group (docs/protocols.md 1.2).
  EXPECT_EQ(cycles.back().odometry.servo_frame_count, first.odometry.servo_frame_count + 1);
}

// --- group assembly and bad frames

StatusCycle example_cycle() {
  StatusCycle cycle;
  cycle.imu.pitch_rad = 3.0 * kDeg;
  cycle.imu.pitch_rate_radps = -12.0 * kDeg;
  cycle.imu.roll_rad = -1.5 * kDeg;
  cycle.imu.roll_rate_radps = 0.5 * kDeg;
  cycle.imu.yaw_rate_radps = 20.0 * kDeg;
  cycle.odometry.left_wheel_velocity_mps = 1.2;
  cycle.odometry.right_wheel_velocity_mps = 1.3;
  cycle.odometry.servo_frame_count = 65535;
  cycle.odometry.left_wheel_distance_m = 351.25;
  cycle.odometry.right_wheel_distance_m = -12.5;
  cycle.odometry.fore_aft_distance_m = 40000.0;  // beyond 16 bits of counts: the 32-bit path
  cycle.odometry.yaw_displacement_rad = -7.0 * std::numbers::pi;
  cycle.left_motor_torque_nm = 2.5;
  cycle.right_motor_torque_nm = -2.5;
  cycle.status.operational_mode = 2;
  cycle.gain_schedule = 1;
  cycle.status.ui_battery_v = 7.9;
  cycle.status.powerbase_battery_v = 72.25;
  cycle.velocity_command_counts = 166;
  cycle.turn_command_counts = -300;
  return cycle;
}

TEST(SegwayRmp, EncodedGroupDecodesBackWithinOneCount) {
  for (const int yaw_sign : {1, -1}) {
    Config config;
    config.yaw_sign = yaw_sign;
    config.source_id = 9;
    const StatusCycle sent = example_cycle();
    const StatusFrames frames = encode_status(sent, config);
    Decoder decoder(config);
    const StatusCycle* received = nullptr;
    for (std::size_t i = 0; i < 8; ++i) {
      received = decoder.push(frames.frames[i], 5000 + static_cast<TimestampNs>(i)).cycle;
    }
    ASSERT_NE(received, nullptr);
    const double angle_count = kDeg / 7.8;
    EXPECT_NEAR(received->imu.pitch_rad, sent.imu.pitch_rad, angle_count);
    EXPECT_NEAR(received->imu.pitch_rate_radps, sent.imu.pitch_rate_radps, angle_count);
    EXPECT_NEAR(received->imu.roll_rad, sent.imu.roll_rad, angle_count);
    EXPECT_NEAR(received->imu.yaw_rate_radps, sent.imu.yaw_rate_radps, angle_count);
    EXPECT_NEAR(received->odometry.left_wheel_velocity_mps, 1.2, 1.0 / 332.0);
    EXPECT_EQ(received->odometry.servo_frame_count, 65535);
    EXPECT_NEAR(received->odometry.left_wheel_distance_m, 351.25, 1.0 / 33215.0);
    EXPECT_NEAR(received->odometry.right_wheel_distance_m, -12.5, 1.0 / 33215.0);
    EXPECT_NEAR(received->odometry.fore_aft_distance_m, 40000.0, 1.0 / 33215.0);
    EXPECT_NEAR(received->odometry.yaw_displacement_rad, sent.odometry.yaw_displacement_rad,
                2.0 * std::numbers::pi / 112644.0);
    EXPECT_NEAR(received->left_motor_torque_nm, 2.5, 1.0 / 1094.0);
    EXPECT_EQ(received->status.operational_mode, 2);
    EXPECT_EQ(received->gain_schedule, 1);
    EXPECT_NEAR(received->status.ui_battery_v, 7.9, 0.0125);
    EXPECT_NEAR(received->status.powerbase_battery_v, 72.25, 0.25);
    EXPECT_EQ(received->velocity_command_counts, 166);
    EXPECT_EQ(received->turn_command_counts, -300);
    EXPECT_EQ(received->odometry.header.stamp_ns, 5000);
    EXPECT_EQ(received->imu.header.source_id, 9);
  }
}

TEST(SegwayRmp, YawSignFlipsTheFramesMeaning) {
  const StatusFrames frames = encode_status(example_cycle(), Config{});
  Config flipped;
  flipped.yaw_sign = -1;
  Decoder decoder(flipped);
  for (const CanFrame& frame : frames.frames) {
    (void)decoder.push(frame, 0);
  }
  EXPECT_NEAR(decoder.latest().imu.yaw_rate_radps, -20.0 * kDeg, kDeg / 7.8);
}

TEST(SegwayRmp, LostFrameMakesTheGroupIncomplete) {
  const StatusFrames frames = encode_status(example_cycle(), Config{});
  Decoder decoder;
  for (std::size_t i = 0; i < 8; ++i) {
    if (i == 3) continue;  // 0x403 lost
    EXPECT_EQ(decoder.push(frames.frames[i], 0).cycle, nullptr);
  }
  EXPECT_EQ(decoder.drops().value(DropReason::kIncompleteCycle), 1u);
  // The next complete group is handed out again.
  const StatusCycle* cycle = nullptr;
  for (const CanFrame& frame : frames.frames) {
    cycle = decoder.push(frame, 0).cycle;
  }
  EXPECT_NE(cycle, nullptr);
  EXPECT_EQ(decoder.cycles_decoded(), 1u);
}

TEST(SegwayRmp, BadFramesAreCountedByReason) {
  Decoder decoder;
  CanFrame short_frame = frame_of("401#FFF9000FFFFF00");
  EXPECT_EQ(decoder.push(short_frame, 0).kind, Decoder::FrameKind::kRejected);
  CanFrame extended = frame_of("00000401#FFF9000FFFFF0009");
  EXPECT_EQ(decoder.push(extended, 0).kind, Decoder::FrameKind::kRejected);
  EXPECT_EQ(decoder.push(frame_of("688#0000018A00000000"), 0).kind, Decoder::FrameKind::kIgnored);
  EXPECT_EQ(decoder.push(frame_of("401#R"), 0).kind, Decoder::FrameKind::kRejected);
  EXPECT_EQ(decoder.drops().value(DropReason::kBadLength), 1u);
  EXPECT_EQ(decoder.drops().value(DropReason::kNotStandard), 2u);
  EXPECT_EQ(decoder.drops().value(DropReason::kForeignId), 1u);
}

// --- encoders: the worked examples of docs/protocols.md 1.6

TEST(SegwayRmp, CommandEncoderMatchesTheWorkedExamples) {
  EXPECT_EQ(text_of(encode_command(0, 0)), "413#0000000000000000");
  EXPECT_EQ(text_of(encode_command(166, 0)), "413#00A6000000000000");  // 0.5 m/s on an RMP 200
  EXPECT_EQ(text_of(encode_command(0, 0, 50, 1)), "413#0000000000320001");
  EXPECT_EQ(text_of(encode_command(0, 0, 16, 1)), "413#0000000000100001");  // tractor mode
  EXPECT_EQ(text_of(encode_command(5000, -5000)), "413#0498FC0000000000");  // clamped to limits
  EXPECT_EQ(text_of(encode_shutdown()), "412#0000000000000000");
}

// --- candump log lines (docs/log-formats.md)

TEST(Candump, ParsesAndFormatsTheLogFormat) {
  candump::Record record;
  ASSERT_EQ(candump::parse_line("(1436509052.249713) can0 401#FFF9000FFFFF0009", record),
            candump::ParseError::kNone);
  EXPECT_EQ(record.stamp_ns, 1436509052'249713000);
  EXPECT_STREQ(record.interface.data(), "can0");
  EXPECT_EQ(record.frame.id, 0x401u);
  EXPECT_EQ(record.frame.dlc, 8);
  EXPECT_EQ(record.frame.data[7], 0x09);
  char line[64];
  const std::size_t length = candump::format_line(record, line);
  EXPECT_EQ(std::string(line, length), "(1436509052.249713) can0 401#FFF9000FFFFF0009");

  ASSERT_EQ(candump::parse_line("(0.000001) vcan10 1ABCDEF0#", record), candump::ParseError::kNone);
  EXPECT_TRUE(record.frame.extended);
  EXPECT_EQ(record.frame.dlc, 0);
  EXPECT_EQ(std::string(line, candump::format_line(record, line)), "(0.000001) vcan10 1ABCDEF0#");
}

TEST(Candump, RejectsMalformedLinesWithAReason) {
  candump::Record record;
  EXPECT_EQ(candump::parse_line("", record), candump::ParseError::kNotAFrame);
  EXPECT_EQ(candump::parse_line("# comment", record), candump::ParseError::kNotAFrame);
  EXPECT_EQ(candump::parse_line("1.0 can0 401#00", record), candump::ParseError::kBadTimestamp);
  EXPECT_EQ(candump::parse_line("(1.5) can0 401#00", record), candump::ParseError::kBadTimestamp);
  EXPECT_EQ(candump::parse_line("(14365436509052.000000) can0 401#00", record),
            candump::ParseError::kBadTimestamp);
  EXPECT_EQ(candump::parse_line("(1.-00001) can0 401#00", record),
            candump::ParseError::kBadTimestamp);
  EXPECT_EQ(candump::parse_line("(1.000000) 401#00", record), candump::ParseError::kBadInterface);
  EXPECT_EQ(candump::parse_line(std::string_view("(1.000000) ca\0n 401#00", 22), record),
            candump::ParseError::kBadInterface);
  EXPECT_EQ(candump::parse_line("(1.000000) can0 801#00", record),
            candump::ParseError::kBadIdentifier);
  EXPECT_EQ(candump::parse_line("(1.000000) can0 40#00", record),
            candump::ParseError::kBadIdentifier);
  EXPECT_EQ(candump::parse_line("(1.000000) can0 401#0", record), candump::ParseError::kBadData);
  EXPECT_EQ(candump::parse_line("(1.000000) can0 401#000102030405060708", record),
            candump::ParseError::kBadData);
  EXPECT_EQ(candump::parse_line("(1.000000) can0 401##100", record), candump::ParseError::kBadData);
  EXPECT_EQ(candump::parse_line("(1.000000) can0 401#0G", record), candump::ParseError::kBadData);
}

TEST(Candump, ReadsOrcaStyleIdBytesLines) {
  candump::Record record;
  ASSERT_EQ(candump::parse_id_bytes_line("id:0680 00 05 00 80 00 00 3E 57", record),
            candump::ParseError::kNone);
  EXPECT_EQ(record.frame.id, 0x680u);
  EXPECT_EQ(record.frame.dlc, 8);
  EXPECT_EQ(record.frame.data[3], 0x80);
  EXPECT_EQ(candump::parse_id_bytes_line("id:0680 00 05 00 80 00 00 3E 57 11", record),
            candump::ParseError::kBadData);
  EXPECT_EQ(candump::parse_id_bytes_line("id:0X80 00", record),
            candump::ParseError::kBadIdentifier);
}

}  // namespace
}  // namespace blockmap::hal::protocol::segway_rmp
