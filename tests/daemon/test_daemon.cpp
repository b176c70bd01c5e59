// The on-robot daemon (firmware_host/daemon): the simulated robot through the reader-queue-
// pipeline threads maps exactly what the single-threaded run maps; devices that are not there
// are reported and retried while the daemon keeps running; a stop request flushes everything.
#include "daemon/daemon.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli.hpp"
#include "cli_runner.hpp"
#include "daemon_walls.hpp"
#include "long_test.hpp"
#include "scratch.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;
using testing::read_file;
using testing::run_cli;
using testing::Wall;
using testing::walls_of;
using testing::within_spread;

using blockmap::testing::scratch;

fs::path write_config(const std::string& name, const std::string& text) {
  fs::path path = scratch(name + ".toml");
  std::ofstream(path) << text;
  return path;
}

// planes.json without its "seconds" (the wall time, which differs between any two runs).
std::string without_seconds(const std::string& planes_json) {
  nlohmann::json list = nlohmann::json::parse(planes_json);
  list.erase("seconds");
  return list.dump();
}

TEST(Daemon, TheSimulatedRobotThroughTheThreadsMapsWhatTheSingleThreadedRunMaps) {
  BLOCKMAP_LONG_TEST();
  const fs::path threaded = scratch("threaded");
  const fs::path single = scratch("single");
  const fs::path config = write_config("sim", "[devices]\nrobot = \"sim:usc_block\"\n");
  const testing::CliResult daemon = run_cli(
      {"run", "--config", config.string(), "--duration-s", "25", "--out", threaded.string()});
  ASSERT_EQ(daemon.status, kExitOk) << daemon.err;
  EXPECT_EQ(daemon.err.rfind("memory: ", 0), 0u) << "the memory report comes first";
  EXPECT_NE(daemon.err.find("device sim:usc_block: the simulated robot"), std::string::npos)
      << daemon.err;
  const testing::CliResult run = run_cli({"run", "--duration-s", "25", "--out", single.string()});
  ASSERT_EQ(run.status, kExitOk) << run.err;
  // The merge hands the mapper the messages in time order however the threads ran: the
  // same stream, trajectory and map, byte for byte.
  for (const char* file : {"planes.bin", "planes.jsonl", "trajectory.csv", "buildings.json"}) {
    const std::string a = read_file(threaded / file);
    EXPECT_FALSE(a.empty()) << file;
    EXPECT_TRUE(a == read_file(single / file)) << file << " differs";
  }
  EXPECT_EQ(without_seconds(read_file(threaded / "planes.json")),
            without_seconds(read_file(single / "planes.json")));
  // Health: a record per second of data, each device's counters and the mapper's.
  std::istringstream lines(read_file(threaded / "health.jsonl"));
  std::size_t records = 0;
  nlohmann::json last;
  for (std::string line; std::getline(lines, line); ++records) {
    last = nlohmann::json::parse(line);
  }
  EXPECT_GE(records, 20u);
  ASSERT_EQ(last["devices"].size(), 4u) << last.dump();
  for (const nlohmann::json& device : last["devices"]) {
    EXPECT_EQ(device["state"], "up") << device.dump();
    EXPECT_GT(device["messages"].get<int>(), 0) << device.dump();
    EXPECT_EQ(device["rejected"].get<int>(), 0) << device.dump();
  }
  EXPECT_GT(last["mapper"]["points"].get<double>(), 100000.0);
  EXPECT_EQ(last["mapper"]["late"].get<int>(), 0);
  fs::remove_all(threaded);
  fs::remove_all(single);
  fs::remove(config);
}

TEST(Daemon, RecordedLogsThroughTheThreadsMapWhatReplayMaps) {
  BLOCKMAP_LONG_TEST();
  const fs::path logs = scratch("logs");
  const fs::path threaded = scratch("replay_threaded");
  const fs::path single = scratch("replay_single");
  const testing::CliResult recorded =
      run_cli({"simulate", "--world", "usc_block", "--duration-s", "25", "--out", logs.string()});
  ASSERT_EQ(recorded.status, kExitOk) << recorded.err;
  const fs::path config =
      write_config("replay", "[devices]\nrobot = \"replay:" + logs.string() + "\"\n");
  const testing::CliResult daemon =
      run_cli({"run", "--config", config.string(), "--out", threaded.string()});
  ASSERT_EQ(daemon.status, kExitOk) << daemon.err;
  EXPECT_NE(daemon.err.find("device replay:" + logs.string() + ": recorded logs, 2 lasers"),
            std::string::npos)
      << daemon.err;
  const testing::CliResult replay = run_cli({"replay", logs.string(), "--out", single.string()});
  ASSERT_EQ(replay.status, kExitOk) << replay.err;
  for (const char* file : {"planes.bin", "planes.jsonl", "trajectory.csv", "buildings.json"}) {
    const std::string a = read_file(threaded / file);
    EXPECT_FALSE(a.empty()) << file;
    EXPECT_TRUE(a == read_file(single / file)) << file << " differs";
  }
  // Nothing recorded was dropped on the way: every scan in the logs reached the mapper.
  std::istringstream lines(read_file(threaded / "health.jsonl"));
  nlohmann::json last;
  for (std::string line; std::getline(lines, line);) {
    last = nlohmann::json::parse(line);
  }
  int scans = 0;
  for (const nlohmann::json& device : last["devices"]) {
    EXPECT_EQ(device["rejected"].get<int>(), 0) << device.dump();
    if (device["name"].get<std::string>().rfind("laser_", 0) == 0) {
      scans += device["messages"].get<int>();
    }
  }
  EXPECT_EQ(last["mapper"]["scans"].get<int>(), scans);
  const fs::path missing = write_config("no_logs", "[devices]\nrobot = \"replay:/nonexistent\"\n");
  const testing::CliResult none = run_cli({"run", "--config", missing.string()});
  EXPECT_EQ(none.status, kExitUsage);
  EXPECT_EQ(none.err,
            "blockmap: run: devices.robot: /nonexistent is not a folder of device logs\n");
  fs::remove_all(logs);
  fs::remove_all(threaded);
  fs::remove_all(single);
  fs::remove(config);
  fs::remove(missing);
}

TEST(Daemon, ABadConfigIsOneLineAndNothingStarts) {
  const fs::path out = scratch("bad");
  const fs::path config =
      write_config("bad", "[devices]\nbase = \"can:can0\"\nlasers = [\"serial:/dev/x@123\"]\n");
  const testing::CliResult result =
      run_cli({"run", "--config", config.string(), "--out", out.string()});
  EXPECT_NE(result.status, kExitOk);
  EXPECT_NE(result.err.find("devices.lasers[0]"), std::string::npos) << result.err;
  EXPECT_EQ(result.err.find('\n'), result.err.size() - 1) << result.err;
  EXPECT_FALSE(fs::exists(out)) << "nothing starts";
  const fs::path three = write_config(
      "three",
      "[devices]\nbase = \"can:can0\"\nlasers = [\"serial:/a@9600\", \"serial:/b@9600\", "
      "\"serial:/c@9600\"]\n");
  const testing::CliResult too_many =
      run_cli({"run", "--config", three.string(), "--out", out.string()});
  EXPECT_NE(too_many.status, kExitOk);
  EXPECT_NE(too_many.err.find("devices.lasers: 3 devices for the robot's 2 lasers"),
            std::string::npos)
      << too_many.err;
  fs::remove(config);
  fs::remove(three);
}

// A CAN interface that is never there (the host's kernel has no CAN).
class AbsentCan final : public daemon::CanOpener {
 public:
  class NoBus final : public hal::CanBus {
   protected:
    hal::CanReceiveResult do_receive(hal::CanFrame& /*frame*/, TimestampNs /*timeout*/) override {
      return {IoStatus::kDeviceLost, 0};
    }
    IoStatus do_send(const hal::CanFrame& /*frame*/) override { return IoStatus::kDeviceLost; }
    IoStatus do_set_filters(std::span<const hal::CanFilter> /*filters*/) override {
      return IoStatus::kOk;
    }
  };
  hal::CanBus& bus() override { return bus_; }
  std::string open(const hal::DeviceAddress& address) override {
    ++opens;
    return address.name + ": no such interface";
  }
  void close() override {}
  std::atomic<int> opens{0};

 private:
  NoBus bus_;
};

TEST(Daemon, DevicesThatAreNotThereAreReportedAndRetriedUntilStopped) {
  const fs::path out = scratch("absent");
  daemon::DaemonOptions options;
  options.config.base = hal::DeviceAddress{hal::DeviceBackend::kCan, "can7"};
  options.config.gps =
      hal::DeviceAddress{hal::DeviceBackend::kSerial, "/dev/blockmap-no-gps", 9600};
  options.config.reconnect_first_s = 0.02;
  options.config.reconnect_max_s = 0.08;
  options.config_source = "robot.toml";
  options.mapping.out = out.string();
  auto can = std::make_unique<AbsentCan>();
  AbsentCan* can_seen = can.get();
  daemon::Daemon daemon(options, std::move(can));
  std::ostringstream err;
  ASSERT_EQ(daemon.start(err), "");
  EXPECT_NE(err.str().find("device base: connecting (can7: no such interface); retrying"),
            std::string::npos)
      << err.str();
  EXPECT_NE(err.str().find("device gps: connecting (serial port /dev/blockmap-no-gps"),
            std::string::npos)
      << err.str();
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(600));
    daemon.request_stop();
  });
  EXPECT_EQ(daemon.run(err), kExitOk) << err.str();
  stopper.join();
  // Backing off: 20, 40, 80, 80 ... ms, so a handful of tries in 0.6 s, not hundreds.
  EXPECT_GE(can_seen->opens.load(), 4);
  EXPECT_LE(can_seen->opens.load(), 15);
  EXPECT_NE(err.str().find("daemon: stopping"), std::string::npos) << err.str();
  EXPECT_TRUE(fs::exists(out / "planes.json")) << "the outputs are written at the end";
  fs::remove_all(out);
}

TEST(Daemon, TheModernVariantsTimsAreOpenedOverUsbAndRetriedWhenAbsent) {
  const fs::path out = scratch("tim");
  daemon::DaemonOptions options;
  options.config = hal::config::load_daemon_config(fs::path(BLOCKMAP_PROJECT_DIR) / "config" /
                                                   "rmp_tim_onboard.toml");
  options.config.base = hal::DeviceAddress{hal::DeviceBackend::kCan, "can7"};
  options.config.gps =
      hal::DeviceAddress{hal::DeviceBackend::kSerial, "/dev/blockmap-no-gps", 9600};
  options.config.reconnect_first_s = 0.02;
  options.config.reconnect_max_s = 0.08;
  options.config_source = "rmp_tim_onboard.toml";
  options.mapping.out = out.string();
  daemon::Daemon daemon(options, std::make_unique<AbsentCan>());
  std::ostringstream err;
  ASSERT_EQ(daemon.start(err), "");
  // This machine has no TiM on its bus (the arm64 guest's tests open one, tim_gadget's).
  EXPECT_NE(err.str().find("device laser_horizontal: connecting (usb:19a2:5001:18340001: "),
            std::string::npos)
      << err.str();
  EXPECT_NE(err.str().find("device laser_vertical: connecting (usb:19a2:5001:18340002: "),
            std::string::npos)
      << err.str();
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    daemon.request_stop();
  });
  EXPECT_EQ(daemon.run(err), kExitOk) << err.str();
  stopper.join();
  fs::remove_all(out);
}

TEST(Daemon, ALaserOnTheWrongKindOfPortForTheRobotsSpecIsOneLine) {
  const fs::path config =
      write_config("tim_on_serial",
                   "[robot]\nspec = \"rmp_tim\"\n[devices]\nbase = \"can:can0\"\n"
                   "lasers = [\"serial:/dev/ttyUSB0@500000\"]\n");
  const testing::CliResult tim = run_cli({"run", "--config", config.string()});
  EXPECT_NE(tim.status, kExitOk);
  EXPECT_EQ(tim.err,
            "blockmap: run: devices.lasers[0]: \"serial:/dev/ttyUSB0@500000\" for the robot's "
            "laser horizontal, a SICK TiM (on usb:VENDOR:PRODUCT)\n");
  const fs::path lms =
      write_config("lms_on_usb", "[devices]\nbase = \"can:can0\"\nlasers = [\"usb:19a2:5001\"]\n");
  const testing::CliResult on_usb = run_cli({"run", "--config", lms.string()});
  EXPECT_NE(on_usb.status, kExitOk);
  EXPECT_NE(on_usb.err.find("for the robot's laser horizontal, an LMS2xx (on serial:PATH@BAUD)"),
            std::string::npos)
      << on_usb.err;
  // The simulator has no TiM: the modern variant is refused there, naming the laser.
  const testing::CliResult simulated =
      run_cli({"simulate", "--world", "usc_block", "--robot", "rmp_tim", "--out",
               scratch("tim_sim").string(), "--duration-s", "1"});
  EXPECT_NE(simulated.status, kExitOk);
  EXPECT_NE(simulated.err.find("robot rmp_tim: laser horizontal is a SICK TiM (protocol = "
                               "\"tim\"): the simulator has SICK LMS2xx lasers only"),
            std::string::npos)
      << simulated.err;
  fs::remove(config);
  fs::remove(lms);
}

}  // namespace
}  // namespace blockmap::cli

namespace blockmap::cli {
namespace {

nlohmann::json last_health(const fs::path& health_jsonl) {
  std::istringstream lines(read_file(health_jsonl));
  nlohmann::json last;
  for (std::string line; std::getline(lines, line);) {
    last = nlohmann::json::parse(line);
  }
  return last;
}

TEST(Daemon, AMinuteWithoutGpsIsMappedOnOdometryAndTheBlockIsStillTheBlock) {
#if defined(BLOCKMAP_QUICK_WORLDS)
  GTEST_SKIP() << "the host trees drive the block twice, with and without GPS";
#endif
  const fs::path with_gps = scratch("with_gps");
  const fs::path without = scratch("gps_silent");
  const fs::path config = write_config("outage", "[devices]\nrobot = \"sim:usc_block\"\n");
  const testing::CliResult a =
      run_cli({"run", "--config", config.string(), "--out", with_gps.string()});
  ASSERT_EQ(a.status, kExitOk) << a.err;
  // The receiver says nothing from 40 s to 100 s of the 173 s loop: the robot drives a long
  // side and turns a corner on odometry alone.
  const testing::CliResult b = run_cli({"run", "--config", config.string(), "--gps-silent-s", "40",
                                        "100", "--out", without.string()});
  ASSERT_EQ(b.status, kExitOk) << b.err;
  const nlohmann::json health_a = last_health(with_gps / "health.jsonl");
  const nlohmann::json health_b = last_health(without / "health.jsonl");
  // 4 fixes a second were missing for the minute; every scan was still mapped.
  const int fixes_a = health_a["mapper"]["fixes"].get<int>();
  const int fixes_b = health_b["mapper"]["fixes"].get<int>();
  EXPECT_NEAR(fixes_a - fixes_b, 240, 8) << fixes_a << " and " << fixes_b;
  EXPECT_EQ(health_b["mapper"]["scans_projected"], health_a["mapper"]["scans_projected"]);
  // The map: the block's walls, as without the silence (within the filter's own spread).
  const std::vector<Wall> walls_a = walls_of(with_gps / "planes.json", 20000.0);
  const std::vector<Wall> walls_b = walls_of(without / "planes.json", 20000.0);
  EXPECT_GE(walls_a.size(), 3u);
  for (const Wall& wall : walls_a) {
    EXPECT_TRUE(within_spread(wall, walls_b))
        << "a wall mapped with GPS, lost without: n = " << wall.normal.transpose()
        << ", d = " << wall.d;
  }
  for (const Wall& wall : walls_b) {
    EXPECT_TRUE(within_spread(wall, walls_a))
        << "a wall mapped only without GPS: n = " << wall.normal.transpose() << ", d = " << wall.d;
  }
  if (!HasFailure()) {
    fs::remove_all(with_gps);
    fs::remove_all(without);
  }
  fs::remove(config);
}

}  // namespace
}  // namespace blockmap::cli
