// The robot's panel: a status LED and a mapping-enable switch on GPIO lines, and
// the GPS receiver's pulse-per-second line, whose edges put the fixes on the robot's clock
// exactly (hal::FixConverter::on_pps).
//
// The LED says how the daemon is at a glance, from across a car park:
//   steady on     mapping, every device up
//   fast blink    mapping, but a device is down or silent (the map goes on with the rest)
//   slow blink    paused by the switch (pose is still tracked)
//   off           not running
// The switch pauses mapping while it is off: the scans are dropped (counted), odometry and GPS
// go on, so the pose is right when it is switched on again. Its thread follows the line's
// edges and takes the level once the line has been still for the debounce time, so that a
// bouncing contact makes one change, not a dozen.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <thread>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/config/daemon_config.hpp"
#include "blockmap/hal/device_address.hpp"
#include "blockmap/hal/gpio_line.hpp"

namespace blockmap::cli::daemon {

enum class LedPattern : std::uint8_t { kOff, kSteady, kFastBlink, kSlowBlink };
[[nodiscard]] const char* to_string(LedPattern pattern) noexcept;

[[nodiscard]] LedPattern led_pattern(bool mapping_enabled, bool every_device_up) noexcept;
// The LED's level at `now_ns` (fast: 4 Hz, slow: 1 Hz, half on).
[[nodiscard]] bool led_level(LedPattern pattern, TimestampNs now_ns) noexcept;

enum class GpioUse : std::uint8_t { kOutput, kInputWithEdges };

// Where a gpio: address is opened: libgpiod on the robot; tests give their own.
class GpioOpener {
 public:
  GpioOpener() = default;
  GpioOpener(const GpioOpener&) = delete;
  GpioOpener& operator=(const GpioOpener&) = delete;
  virtual ~GpioOpener() = default;
  // The line, or none with `error` set to one line why not.
  [[nodiscard]] virtual std::unique_ptr<hal::GpioLine> open(const hal::DeviceAddress& address,
                                                            GpioUse use, bool active_low,
                                                            std::string& error) = 0;
};

[[nodiscard]] std::unique_ptr<GpioOpener> gpiod_opener();

class Panel {
 public:
  explicit Panel(std::unique_ptr<GpioOpener> opener);
  ~Panel();
  Panel(const Panel&) = delete;
  Panel& operator=(const Panel&) = delete;

  // Opens the configured lines (none configured: nothing to do) and prints their states; the
  // switch's thread starts here. Empty when it worked, else one line naming the key.
  [[nodiscard]] std::string start(const hal::config::DaemonConfig& config, std::ostream& err);
  // Main thread, every few tens of milliseconds.
  void show(LedPattern pattern, TimestampNs now_ns);
  // Prints the switch's changes since the last call (main thread).
  void report_changes(std::ostream& err);
  // Ends the switch's thread and leaves the LED off.
  void stop();

  // The PPS line's rising edges, stamped by the kernel, for the pipeline thread (none without
  // a gps_pps line). The pipeline takes them every few milliseconds; full (a pipeline stalled
  // for 8 s), new edges are dropped until it drains, and the fixes fall back on the least
  // delay meanwhile.
  [[nodiscard]] SpscQueueRef<TimestampNs>* pps_edges() noexcept {
    return pps_ != nullptr ? &pps_queue_ : nullptr;
  }
  [[nodiscard]] std::uint64_t pps_edges_seen() const noexcept {
    return pps_seen_.load(std::memory_order_relaxed);
  }

  // True without a switch. Read by the pipeline thread.
  [[nodiscard]] const std::atomic<bool>& mapping_enabled() const noexcept {
    return mapping_enabled_;
  }
  [[nodiscard]] std::uint64_t switch_changes() const noexcept {
    return switch_changes_.load(std::memory_order_relaxed);
  }
  // The switch line's failed reads (any thread).
  [[nodiscard]] std::uint64_t switch_failures() const noexcept {
    return switch_failures_.load(std::memory_order_relaxed);
  }
  // The LED's failed writes (main thread).
  [[nodiscard]] std::uint64_t led_failures() const noexcept;

 private:
  void follow_switch();
  void follow_pps();

  std::unique_ptr<GpioOpener> opener_;
  std::unique_ptr<hal::GpioLine> led_;
  std::unique_ptr<hal::GpioLine> switch_;
  TimestampNs debounce_ns_ = 0;
  bool led_shown_ = false;
  bool led_known_ = false;
  std::atomic<bool> mapping_enabled_{true};
  std::atomic<std::uint64_t> switch_changes_{0};
  std::atomic<std::uint64_t> switch_failures_{0};
  std::uint64_t changes_reported_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  std::unique_ptr<hal::GpioLine> pps_;
  std::array<TimestampNs, 9> pps_slots_{};  // 8 edges: 8 s of pulses
  SpscQueueRef<TimestampNs> pps_queue_{pps_slots_};
  std::atomic<std::uint64_t> pps_seen_{0};
  std::thread pps_thread_;
};

}  // namespace blockmap::cli::daemon
