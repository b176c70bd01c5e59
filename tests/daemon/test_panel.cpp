// The robot's panel (firmware_host/daemon/panel.hpp): what the status LED shows, the
// mapping-enable switch with a bouncing contact and a failing line, and the daemon mapping
// nothing while the switch is off but still tracking its pose.
#include "daemon/panel.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli.hpp"
#include "cli_runner.hpp"
#include "daemon/daemon.hpp"
#include "long_test.hpp"
#include "scratch.hpp"

namespace blockmap::cli::daemon {
namespace {

namespace fs = std::filesystem;
using testing::read_file;

// A GPIO line another thread can drive, as the kernel drives a real one.
class FakeLine final : public hal::GpioLine {
 public:
  explicit FakeLine(bool level) : level_(level) {}

  // The outside world moves the input; a change is an edge.
  void drive(bool level) {
    {
      const std::lock_guard lock(mutex_);
      if (level != level_) {
        edges_.push_back(hal::GpioEdge{IoStatus::kOk, level, ++stamp_ns_});
        level_ = level;
      }
    }
    changed_.notify_all();
  }
  void fail() {
    {
      const std::lock_guard lock(mutex_);
      failing_ = true;
    }
    changed_.notify_all();
  }
  [[nodiscard]] std::vector<bool> history() const {
    const std::lock_guard lock(mutex_);
    return history_;
  }

 protected:
  IoStatus do_set(bool active) override {
    const std::lock_guard lock(mutex_);
    level_ = active;
    history_.push_back(active);
    return IoStatus::kOk;
  }
  IoStatus do_get(bool& active) override {
    const std::lock_guard lock(mutex_);
    if (failing_) {
      return IoStatus::kDeviceLost;
    }
    active = level_;
    return IoStatus::kOk;
  }
  hal::GpioEdge do_wait_edge(TimestampNs timeout_ns) override {
    std::unique_lock lock(mutex_);
    changed_.wait_for(lock, std::chrono::nanoseconds(timeout_ns),
                      [&] { return failing_ || !edges_.empty(); });
    if (failing_) {
      return hal::GpioEdge{IoStatus::kDeviceLost, false, 0};
    }
    if (edges_.empty()) {
      return hal::GpioEdge{IoStatus::kTimedOut, false, 0};
    }
    const hal::GpioEdge edge = edges_.front();
    edges_.pop_front();
    return edge;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool level_;
  bool failing_ = false;
  TimestampNs stamp_ns_ = 0;
  std::deque<hal::GpioEdge> edges_;
  std::vector<bool> history_;
};

// Hands out fake lines and keeps a hand on them; a chip named "missing" is not there.
class FakeOpener final : public GpioOpener {
 public:
  explicit FakeOpener(bool switch_level) : switch_level_(switch_level) {}
  std::unique_ptr<hal::GpioLine> open(const hal::DeviceAddress& address, GpioUse use,
                                      bool /*active_low*/, std::string& error) override {
    if (address.name == "missing") {
      error = "missing: cannot open the GPIO chip (No such file or directory)";
      return nullptr;
    }
    auto line = std::make_unique<FakeLine>(use == GpioUse::kOutput ? false : switch_level_);
    if (use == GpioUse::kOutput) {
      led = line.get();
    } else if (address.line_offset == 4) {
      pps = line.get();
    } else {
      switch_line = line.get();
    }
    return line;
  }
  FakeLine* led = nullptr;
  FakeLine* switch_line = nullptr;
  FakeLine* pps = nullptr;

 private:
  bool switch_level_;
};

hal::config::DaemonConfig panel_config() {
  hal::config::DaemonConfig config;
  config.status_led = hal::DeviceAddress{hal::DeviceBackend::kGpio, "gpiochip0", 0, 0, 0, 5};
  config.enable_switch = hal::DeviceAddress{hal::DeviceBackend::kGpio, "gpiochip0", 0, 0, 0, 3};
  config.switch_debounce_s = 0.01;
  return config;
}

bool eventually(const std::function<bool()>& condition) {
  for (int i = 0; i < 400; ++i) {
    if (condition()) {
      return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

TEST(Panel, TheLedSaysMappingDegradedPausedOrStopped) {
  EXPECT_EQ(led_pattern(true, true), LedPattern::kSteady);
  EXPECT_EQ(led_pattern(true, false), LedPattern::kFastBlink);
  EXPECT_EQ(led_pattern(false, true), LedPattern::kSlowBlink);
  EXPECT_EQ(led_pattern(false, false), LedPattern::kSlowBlink) << "paused is what matters then";
  constexpr TimestampNs kMs = 1'000'000;
  EXPECT_TRUE(led_level(LedPattern::kSteady, 700 * kMs));
  EXPECT_FALSE(led_level(LedPattern::kOff, 100 * kMs));
  // Fast: 4 Hz, half on; slow: 1 Hz, half on.
  EXPECT_TRUE(led_level(LedPattern::kFastBlink, 100 * kMs));
  EXPECT_FALSE(led_level(LedPattern::kFastBlink, 150 * kMs));
  EXPECT_TRUE(led_level(LedPattern::kFastBlink, 260 * kMs));
  EXPECT_TRUE(led_level(LedPattern::kSlowBlink, 400 * kMs));
  EXPECT_FALSE(led_level(LedPattern::kSlowBlink, 600 * kMs));
}

TEST(Panel, TheLedIsWrittenOnlyWhenItChangesAndIsLeftOff) {
  auto opener = std::make_unique<FakeOpener>(true);
  FakeOpener& lines = *opener;
  Panel panel(std::move(opener));
  std::ostringstream err;
  ASSERT_EQ(panel.start(panel_config(), err), "");
  EXPECT_NE(err.str().find("status LED gpio:gpiochip0:5: up"), std::string::npos) << err.str();
  constexpr TimestampNs kMs = 1'000'000;
  for (TimestampNs t = 0; t < 1000 * kMs; t += 50 * kMs) {
    panel.show(LedPattern::kFastBlink, t);
  }
  panel.show(LedPattern::kSteady, 1000 * kMs);
  panel.show(LedPattern::kSteady, 1050 * kMs);
  panel.stop();
  // Four on-off cycles in a second, then on, then off at the stop.
  const std::vector<bool> expected{true, false, true, false, true, false, true, false, true, false};
  EXPECT_EQ(lines.led->history(), expected);
}

TEST(Panel, ABouncingSwitchIsOneChangeAndPausesMapping) {
  auto opener = std::make_unique<FakeOpener>(false);
  FakeOpener& lines = *opener;
  Panel panel(std::move(opener));
  std::ostringstream err;
  ASSERT_EQ(panel.start(panel_config(), err), "");
  EXPECT_FALSE(panel.mapping_enabled().load()) << "the level at start-up counts";
  EXPECT_NE(err.str().find("enable switch gpio:gpiochip0:3: off, mapping paused"),
            std::string::npos)
      << err.str();
  // Switched on through a contact that bounces five times within a millisecond.
  for (const bool level : {true, false, true, false, true, false, true}) {
    lines.switch_line->drive(level);
  }
  ASSERT_TRUE(eventually([&] { return panel.mapping_enabled().load(); }));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(panel.switch_changes(), 1u);
  std::ostringstream changes;
  panel.report_changes(changes);
  EXPECT_EQ(changes.str(), "enable switch: on, mapping\n");
  lines.switch_line->drive(false);
  ASSERT_TRUE(eventually([&] { return !panel.mapping_enabled().load(); }));
  EXPECT_EQ(panel.switch_changes(), 2u);
  // A line that fails keeps the last level, and says so in its counter.
  lines.switch_line->fail();
  ASSERT_TRUE(eventually([&] { return panel.switch_failures() > 0; }));
  EXPECT_FALSE(panel.mapping_enabled().load());
  panel.stop();
}

TEST(Panel, ALineThatIsNotThereIsOneLineNamingTheKey) {
  hal::config::DaemonConfig config = panel_config();
  config.enable_switch->name = "missing";
  Panel panel(std::make_unique<FakeOpener>(true));
  std::ostringstream err;
  EXPECT_EQ(panel.start(config, err),
            "devices.enable_switch: missing: cannot open the GPIO chip (No such file or "
            "directory)");
  // No panel at all: mapping, nothing opened.
  Panel none(std::make_unique<FakeOpener>(true));
  EXPECT_EQ(none.start(hal::config::DaemonConfig{}, err), "");
  EXPECT_TRUE(none.mapping_enabled().load());
}

TEST(Panel, ThePpsLinesRisingEdgesReachThePipelineWithTheirStamps) {
  hal::config::DaemonConfig config;
  config.gps_pps = hal::DeviceAddress{hal::DeviceBackend::kGpio, "gpiochip0", 0, 0, 0, 4};
  auto opener = std::make_unique<FakeOpener>(false);
  FakeOpener& lines = *opener;
  Panel panel(std::move(opener));
  EXPECT_EQ(panel.pps_edges(), nullptr) << "not before it is opened";
  std::ostringstream err;
  ASSERT_EQ(panel.start(config, err), "");
  EXPECT_NE(err.str().find("GPS PPS gpio:gpiochip0:4: up"), std::string::npos) << err.str();
  auto* const edges = panel.pps_edges();
  ASSERT_NE(edges, nullptr);
  // Three pulses: up at the second, down 100 ms later (the fake stamps its edges 1, 2, 3 ...).
  for (int pulse = 0; pulse < 3; ++pulse) {
    lines.pps->drive(true);
    lines.pps->drive(false);
  }
  ASSERT_TRUE(eventually([&] { return panel.pps_edges_seen() == 3; }));
  std::vector<TimestampNs> stamps;
  for (TimestampNs stamp = 0; edges->try_pop(stamp);) {
    stamps.push_back(stamp);
  }
  EXPECT_EQ(stamps, (std::vector<TimestampNs>{1, 3, 5})) << "the rising edges only";
  EXPECT_TRUE(panel.mapping_enabled().load()) << "a PPS line is not a switch";
  panel.stop();
}

using blockmap::testing::scratch;

struct SwitchRun {
  int status = 0;
  std::string err;
  std::string last_health;  // the last line of health.jsonl
  std::vector<bool> led;
};

// The simulated robot through the daemon for 20 s of data, with the switch at `level`.
SwitchRun run_with_switch(bool level, const fs::path& out) {
  DaemonOptions options;
  options.config = panel_config();
  options.config.whole_robot = hal::DeviceAddress{hal::DeviceBackend::kSim, "usc_block"};
  options.config_source = "robot.toml";
  options.mapping.out = out.string();
  options.sim.max_duration_s = 20.0;
  auto opener = std::make_unique<FakeOpener>(level);
  FakeOpener& lines = *opener;
  Daemon daemon(options, socket_can_opener(), std::move(opener));
  std::ostringstream err;
  SwitchRun run;
  if (const std::string problem = daemon.start(err); !problem.empty()) {
    run.status = kExitUsage;
    run.err = problem;
    return run;
  }
  run.status = daemon.run(err);
  run.err = err.str();
  std::istringstream lines_of_health(read_file(out / "health.jsonl"));
  for (std::string line; std::getline(lines_of_health, line);) {
    run.last_health = line;
  }
  run.led = lines.led->history();
  return run;
}

TEST(Panel, WithTheSwitchOffTheDaemonTracksThePoseButMapsNothing) {
  BLOCKMAP_LONG_TEST();
  const fs::path on_dir = scratch("on");
  const fs::path off_dir = scratch("off");
  const SwitchRun on = run_with_switch(true, on_dir);
  ASSERT_EQ(on.status, kExitOk) << on.err;
  const SwitchRun off = run_with_switch(false, off_dir);
  ASSERT_EQ(off.status, kExitOk) << off.err;
  const nlohmann::json on_health = nlohmann::json::parse(on.last_health);
  const nlohmann::json off_health = nlohmann::json::parse(off.last_health);
  EXPECT_TRUE(on_health["mapping_enabled"].get<bool>());
  EXPECT_FALSE(off_health["mapping_enabled"].get<bool>());
  EXPECT_EQ(on_health["scans_paused"], 0);
  const int scans = on_health["mapper"]["scans"].get<int>();
  EXPECT_GT(scans, 500);
  EXPECT_EQ(off_health["scans_paused"].get<int>(), scans) << "every scan was held back";
  EXPECT_EQ(off_health["mapper"]["scans"], 0);
  const nlohmann::json planes_on = nlohmann::json::parse(read_file(on_dir / "planes.json"));
  const nlohmann::json planes_off = nlohmann::json::parse(read_file(off_dir / "planes.json"));
  EXPECT_GE(planes_on["planes"].size(), 3u);
  EXPECT_EQ(planes_off["planes"].size(), 0u);
  // The pose went on: the same trajectory, with the map or without.
  EXPECT_EQ(on_health["mapper"]["base_samples"], off_health["mapper"]["base_samples"]);
  EXPECT_EQ(on_health["mapper"]["fixes"], off_health["mapper"]["fixes"]);
  const std::string trajectory = read_file(on_dir / "trajectory.csv");
  EXPECT_FALSE(trajectory.empty());
  EXPECT_EQ(trajectory, read_file(off_dir / "trajectory.csv"));
  // The LED was lit while mapping and is off once stopped.
  ASSERT_FALSE(on.led.empty());
  EXPECT_TRUE(on.led.front());
  EXPECT_FALSE(on.led.back());
  fs::remove_all(on_dir);
  fs::remove_all(off_dir);
}

}  // namespace
}  // namespace blockmap::cli::daemon
