// The on-robot tables of `blockmap run --config` (hal/config/daemon_config.hpp): every device
// string and daemon setting read, and each mistake one line naming its key, before anything
// starts.
#include <gtest/gtest.h>

#include <string>

#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/daemon_config.hpp"

namespace blockmap::hal::config {
namespace {

std::string error_of(const std::string& text) {
  try {
    static_cast<void>(parse_daemon_config(text, "robot.toml"));
  } catch (const ConfigError& error) {
    return error.what();
  }
  return "(no error)";
}

TEST(DaemonConfig, ReadsThePapersRobot) {
  const DaemonConfig c = parse_daemon_config(R"(
[robot]
spec = "paper_rmp"
[devices]
base = "can:can0"
lasers = ["serial:/dev/ttyUSB0@500000", "serial:/dev/ttyUSB1@38400"]
gps = "serial:/dev/ttyUSB2@9600"
status_led = "gpio:gpiochip0:5"
enable_switch = "gpio:gpiochip0:6"
enable_switch_active_low = true
switch_debounce_s = 0.05
gps_pps = "gpio:gpiochip0:4"
[daemon]
silent_after_s = 1.5
reconnect_first_s = 0.1
reconnect_max_s = 4
health_every_s = 2
snapshot_every_s = 30
realtime_priority = 40
lock_memory = true
scan_queue_messages = 64
)",
                                             "robot.toml");
  EXPECT_EQ(c.robot, "paper_rmp");
  ASSERT_TRUE(c.base);
  EXPECT_EQ(c.base->backend, DeviceBackend::kCan);
  EXPECT_EQ(c.base->name, "can0");
  ASSERT_EQ(c.lasers.size(), 2u);
  EXPECT_EQ(c.lasers[0]->baud, 500000u);
  EXPECT_EQ(c.lasers[1]->name, "/dev/ttyUSB1");
  EXPECT_EQ(c.gps->baud, 9600u);
  EXPECT_EQ(c.status_led->line_offset, 5u);
  EXPECT_EQ(c.enable_switch->name, "gpiochip0");
  EXPECT_FALSE(c.status_led_active_low);
  EXPECT_TRUE(c.enable_switch_active_low);
  EXPECT_DOUBLE_EQ(c.switch_debounce_s, 0.05);
  EXPECT_EQ(c.gps_pps->line_offset, 4u);
  EXPECT_FALSE(c.gps_pps_active_low);
  EXPECT_FALSE(c.whole_robot);
  EXPECT_DOUBLE_EQ(c.silent_after_s, 1.5);
  EXPECT_DOUBLE_EQ(c.reconnect_max_s, 4.0);
  EXPECT_DOUBLE_EQ(c.snapshot_every_s, 30.0);
  EXPECT_EQ(c.realtime_priority, 40);
  EXPECT_TRUE(c.lock_memory);
  EXPECT_EQ(c.scan_queue_messages, 64u);
  EXPECT_EQ(c.base_queue_messages, DaemonConfig{}.base_queue_messages);
}

TEST(DaemonConfig, AnEmptyLaserStringLeavesThatLaserOut) {
  const DaemonConfig c = parse_daemon_config(
      "[devices]\nbase = \"can:can0\"\nlasers = [\"\", \"serial:/dev/ttyS1@38400\"]\n", "r.toml");
  ASSERT_EQ(c.lasers.size(), 2u);
  EXPECT_FALSE(c.lasers[0]);
  EXPECT_TRUE(c.lasers[1]);
}

TEST(DaemonConfig, TheSimulatedRobotTakesTheWholeRobot) {
  const DaemonConfig c = parse_daemon_config("[devices]\nrobot = \"sim:benning\"\n", "r.toml");
  ASSERT_TRUE(c.whole_robot);
  EXPECT_EQ(c.whole_robot->backend, DeviceBackend::kSim);
  EXPECT_EQ(c.whole_robot->name, "benning");
  EXPECT_TRUE(has_devices("[devices]\nrobot = \"sim:x\"\n", "r.toml"));
  EXPECT_FALSE(has_devices("[planes]\n", "r.toml"));
}

TEST(DaemonConfig, EveryMistakeIsOneLineNamingItsKey) {
  const struct {
    const char* text;
    const char* expected;
  } cases[] = {
      {"[devices]\nbase = \"can:can0\"\nbsae = 1\n", "devices.bsae"},
      {"[devices]\nbase = \"serial:/dev/ttyUSB0@38400\"\n", "devices.base"},
      {"[devices]\nbase = \"can:\"\n", "devices.base"},
      {"[devices]\nbase = \"can:can0\"\nlasers = [\"can:can1\"]\n", "devices.lasers[0]"},
      {"[devices]\nbase = \"can:can0\"\nlasers = [\"usb:19a2:5001\", \"usb:19a2:5001\"]\n",
       "devices.lasers[1]: \"usb:19a2:5001\": two lasers with the same ids are told apart by "
       "their serial numbers"},
      {"[devices]\nbase = \"can:can0\"\nlasers = [\"usb:19a2:5001:1\", \"usb:19a2:5001\"]\n",
       "devices.lasers[1]"},
      {"[devices]\nbase = \"can:can0\"\nlasers = [\"gpio:gpiochip0:1\"]\n",
       "a TiM on USB (usb:19a2:5001)"},
      {"[devices]\nbase = \"can:can0\"\nlasers = [\"serial:/dev/ttyS0@12345\"]\n",
       "devices.lasers[0]"},
      {"[devices]\nbase = \"can:can0\"\nlasers = \"serial:/dev/ttyS0@9600\"\n", "devices.lasers"},
      {"[devices]\nbase = \"can:can0\"\ngps = \"gpio:gpiochip0:1\"\n", "devices.gps"},
      {"[devices]\nbase = \"can:can0\"\nstatus_led = \"can:can1\"\n", "devices.status_led"},
      {"[devices]\nbase = \"can:can0\"\nlms_power_up_baud = 4800\n", "devices.lms_power_up_baud"},
      {"[devices]\nbase = \"can:can0\"\nstatus_led = \"gpio:gpiochip0:5\"\n"
       "enable_switch = \"gpio:gpiochip0:5\"\n",
       "devices.enable_switch"},
      {"[devices]\nbase = \"can:can0\"\nswitch_debounce_s = 2\n", "devices.switch_debounce_s"},
      {"[devices]\nbase = \"can:can0\"\ngps_pps = \"serial:/dev/pps0@9600\"\n", "devices.gps_pps"},
      {"[devices]\nbase = \"can:can0\"\nstatus_led = \"gpio:gpiochip0:4\"\n"
       "gps_pps = \"gpio:gpiochip0:4\"\n",
       "devices.gps_pps: is the status LED's or the enable switch's line"},
      {"[devices]\nbase = \"can:can0\"\nstatus_led_active_low = 1\n",
       "devices.status_led_active_low"},
      {"[devices]\nlasers = [\"serial:/dev/ttyS0@9600\"]\n", "devices.base"},
      {"[devices]\nrobot = \"sim:usc_block\"\nbase = \"can:can0\"\n", "devices.base"},
      {"[devices]\nrobot = \"can:can0\"\n", "devices.robot"},
      {"[devices]\nbase = \"can:can0\"\n[daemon]\nsilent_after_ms = 5\n", "daemon.silent_after_ms"},
      {"[devices]\nbase = \"can:can0\"\n[daemon]\nsilent_after_s = 0\n", "daemon.silent_after_s"},
      {"[devices]\nbase = \"can:can0\"\n[daemon]\nreconnect_first_s = 2\nreconnect_max_s = 1\n",
       "daemon.reconnect_max_s"},
      {"[devices]\nbase = \"can:can0\"\n[daemon]\nrealtime_priority = 100\n",
       "daemon.realtime_priority"},
      {"[devices]\nbase = \"can:can0\"\n[daemon]\nscan_queue_messages = 0\n",
       "daemon.scan_queue_messages"},
      {"[robot]\nname = \"x\"\n[devices]\nbase = \"can:can0\"\n", "robot.spec"},
      {"[planes]\n", "no [devices] table"},
  };
  for (const auto& c : cases) {
    const std::string error = error_of(c.text);
    EXPECT_NE(error.find(c.expected), std::string::npos) << c.text << "\n-> " << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    EXPECT_EQ(error.rfind("robot.toml", 0), 0u) << error;
  }
}

TEST(DaemonConfig, MoreLaserDevicesThanTheRobotHasLasersIsAnError) {
  const DaemonConfig c = parse_daemon_config(
      "[devices]\nbase = \"can:can0\"\nlasers = [\"serial:/a@9600\", \"serial:/b@9600\", "
      "\"serial:/c@9600\"]\n",
      "r.toml");
  EXPECT_THROW(check_laser_count(c, 2, "r.toml"), ConfigError);
  EXPECT_NO_THROW(check_laser_count(c, 3, "r.toml"));
}

}  // namespace
}  // namespace blockmap::hal::config

namespace blockmap::hal::config {
namespace {

TEST(DaemonConfig, TheShippedOnRobotConfigReads) {
  const DaemonConfig c = load_daemon_config(std::filesystem::path(BLOCKMAP_PROJECT_DIR) / "config" /
                                            "paper_rmp_onboard.toml");
  EXPECT_EQ(c.robot, "paper_rmp");
  ASSERT_TRUE(c.base);
  EXPECT_EQ(c.lasers.size(), 2u);
  ASSERT_TRUE(c.gps);
  EXPECT_EQ(c.gps->baud, 9600u);
  EXPECT_EQ(c.lms_power_up_baud, 9600u);
  // The modern variant: two TiMs on USB, told apart by their serial numbers.
  const DaemonConfig tim = load_daemon_config(std::filesystem::path(BLOCKMAP_PROJECT_DIR) /
                                              "config" / "rmp_tim_onboard.toml");
  EXPECT_EQ(tim.robot, "rmp_tim");
  ASSERT_EQ(tim.lasers.size(), 2u);
  EXPECT_EQ(tim.lasers[0]->backend, DeviceBackend::kUsb);
  EXPECT_EQ(tim.lasers[0]->vendor_id, 0x19a2);
  EXPECT_EQ(tim.lasers[1]->name, "18340002");
}

}  // namespace
}  // namespace blockmap::hal::config
