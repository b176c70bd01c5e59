// SocketCAN (hal/linux/socket_can_bus.hpp) on a real kernel's vcan0. The host kernel here has no
// CAN at all (docs/design.md): these tests skip there and run in the arm64 guest, where
// scripts/guest-test loads can, can-raw, can-dev and vcan and brings vcan0 up.
#include <gtest/gtest.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <ctime>
#include <string>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/linux/socket_can_bus.hpp"
#include "blockmap/hal/linux/steady_clock.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "test_units.hpp"

namespace blockmap::hal::linux_backend {
namespace {

using blockmap::testing::kMs;

// Whether this kernel has SocketCAN and a vcan0 to use.
bool have_vcan0() {
  const int fd = ::socket(PF_CAN, SOCK_RAW, 1 /* CAN_RAW */);
  if (fd < 0) {
    return false;
  }
  ::close(fd);
  return ::if_nametoindex("vcan0") != 0;
}

class SocketCanTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_vcan0()) {
      GTEST_SKIP() << "no SocketCAN with vcan0 in this kernel (the guest of scripts/guest-test "
                      "has one)";
    }
    ASSERT_EQ(sender_.open("vcan0"), "");
    ASSERT_EQ(receiver_.open("vcan0"), "");
  }

  CanReceiveResult receive(CanFrame& frame) { return receiver_.receive(frame, 500 * kMs); }

  SocketCanBus sender_;
  SocketCanBus receiver_;
};

TEST_F(SocketCanTest, AFrameCrossesTheBusWithItsKernelStamp) {
  CanFrame sent;
  sent.id = 0x401;  // an RMP status frame's id
  sent.dlc = 8;
  sent.data = {0xFF, 0xF9, 0x00, 0x10, 0x80, 0x00, 0x01, 0x02};
  const TimestampNs before = SteadyClock{}.now_ns();
  ASSERT_EQ(sender_.send(sent), IoStatus::kOk);
  CanFrame got;
  const CanReceiveResult result = receive(got);
  const TimestampNs after = SteadyClock{}.now_ns();
  ASSERT_EQ(result.status, IoStatus::kOk);
  EXPECT_EQ(got.id, 0x401u);
  EXPECT_FALSE(got.extended);
  EXPECT_FALSE(got.error);
  EXPECT_EQ(got.dlc, 8);
  EXPECT_EQ(got.data, sent.data);
  // The kernel's receive time, on the monotonic clock: between the send and the read.
  EXPECT_GE(result.stamp_ns, before - 1 * kMs);
  EXPECT_LE(result.stamp_ns, after);
  EXPECT_EQ(receiver_.frames_received(), 1u);
  EXPECT_EQ(sender_.frames_sent(), 1u);

  CanFrame extended;
  extended.id = 0x18FEF100;
  extended.extended = true;
  extended.dlc = 3;
  extended.data = {1, 2, 3};
  ASSERT_EQ(sender_.send(extended), IoStatus::kOk);
  ASSERT_EQ(receive(got).status, IoStatus::kOk);
  EXPECT_TRUE(got.extended);
  EXPECT_EQ(got.id, 0x18FEF100u);
  EXPECT_EQ(got.dlc, 3);
}

TEST_F(SocketCanTest, FiltersPassOnlyTheRmpsIds) {
  // The RMP's status frames are 0x400-0x407: one filter with mask 0x7F8.
  const std::array<CanFilter, 1> rmp = {{{0x400, 0x7F8}}};
  ASSERT_EQ(receiver_.set_filters(rmp), IoStatus::kOk);
  for (const std::uint32_t id : {0x123U, 0x404U, 0x500U, 0x407U}) {
    CanFrame frame;
    frame.id = id;
    frame.dlc = 1;
    ASSERT_EQ(sender_.send(frame), IoStatus::kOk);
  }
  CanFrame got;
  ASSERT_EQ(receive(got).status, IoStatus::kOk);
  EXPECT_EQ(got.id, 0x404u);
  ASSERT_EQ(receive(got).status, IoStatus::kOk);
  EXPECT_EQ(got.id, 0x407u);
  EXPECT_EQ(receiver_.receive(got, 20 * kMs).status, IoStatus::kTimedOut);
  // No filters: everything again.
  ASSERT_EQ(receiver_.set_filters({}), IoStatus::kOk);
  CanFrame other;
  other.id = 0x123;
  ASSERT_EQ(sender_.send(other), IoStatus::kOk);
  ASSERT_EQ(receive(got).status, IoStatus::kOk);
  EXPECT_EQ(got.id, 0x123u);
  const std::array<CanFilter, SocketCanBus::kMaxFilters + 1> too_many{};
  EXPECT_EQ(receiver_.set_filters(too_many), IoStatus::kInvalidArgument);
}

TEST_F(SocketCanTest, TheSegwayBaseDecodesItsStatusFramesFromTheKernel) {
  // The device layer on SocketCAN, with the frames an RMP sends every 10 ms (and the UI's
  // heartbeat, which the base's filters keep off the socket).
  SpscQueue<msg::OdometrySample, 64> odometry;
  SpscQueue<msg::ImuSample, 64> imu;
  devices::SegwayBase base(receiver_, odometry, imu, devices::SegwayBaseConfig{});
  ASSERT_EQ(base.install_filters(), IoStatus::kOk);
  constexpr int kGroups = 20;
  for (int group = 0; group < kGroups; ++group) {
    protocol::segway_rmp::StatusCycle cycle;
    cycle.odometry.fore_aft_distance_m = 0.01 * group;
    cycle.odometry.servo_frame_count = static_cast<std::uint16_t>(group);
    cycle.imu.pitch_rad = 0.05;
    for (const CanFrame& frame :
         protocol::segway_rmp::encode_status(cycle, protocol::segway_rmp::Config{}).frames) {
      ASSERT_EQ(sender_.send(frame), IoStatus::kOk);
    }
    CanFrame heartbeat;
    heartbeat.id = 0x688;
    heartbeat.dlc = 8;
    ASSERT_EQ(sender_.send(heartbeat), IoStatus::kOk);
  }
  for (int polls = 0; base.samples_published() < kGroups && polls < 200; ++polls) {
    static_cast<void>(base.poll(10 * kMs));
  }
  ASSERT_EQ(base.samples_published(), static_cast<std::uint64_t>(kGroups));
  msg::OdometrySample sample;
  for (int group = 0; group < kGroups; ++group) {
    ASSERT_TRUE(odometry.try_pop(sample));
    EXPECT_NEAR(sample.fore_aft_distance_m, 0.01 * group, 1.0 / 33215.0);
  }
  EXPECT_EQ(base.decoder().drops().total(), 0u) << "no foreign frame reached the decoder";
}

TEST(SocketCan, AMissingInterfaceIsOneClearLine) {
  SocketCanBus bus;
  const std::string error = bus.open("nosuchcan0");
  EXPECT_NE(error.find("nosuchcan0"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
  EXPECT_FALSE(bus.is_open());
  EXPECT_NE(bus.open("a_name_far_too_long").find("1 to 15 characters"), std::string::npos);
  CanFrame frame;
  EXPECT_EQ(bus.receive(frame, 0).status, IoStatus::kDeviceLost);
}

}  // namespace
}  // namespace blockmap::hal::linux_backend
