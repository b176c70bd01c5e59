// The on-robot tables of a mapping configuration (`blockmap run --config FILE`):
// [robot] which robot's geometry, [devices] where each device is (hal/device_address.hpp),
// [daemon] how the daemon watches them. A file with a [devices] table maps from those devices;
// without one, `run` maps the built-in simulated block. Every mistake (an unknown key, a
// device string that names no device, a backend the device cannot use, a laser the robot does
// not have) is a ConfigError naming the key, before anything starts. config/README.md lists
// the keys with their defaults.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "blockmap/hal/device_address.hpp"

namespace blockmap::hal::config {

struct DaemonConfig {
  // [robot] spec: a built-in robot (config/robots) or a .toml file: the lasers' mounts, the
  // base's model, the GPS antenna.
  std::string robot = "paper_rmp";

  // [devices]. Either the robot's devices one by one, or `robot = "sim:NAME"` (the simulated
  // robot in its world, faster than real time) / `robot = "replay:DIR"` (recorded logs) for
  // the whole robot.
  std::optional<DeviceAddress> whole_robot;  // sim: or replay:
  std::optional<DeviceAddress> base;         // can:
  // One per laser of the robot, in the order of its [[lasers]]; a missing one maps without it.
  std::vector<std::optional<DeviceAddress>> lasers;
  // The rate the LMS2xx lasers power up at (9600): start-up brings them to their line's rate
  // (docs/protocols.md 2.4). 0: they are at the line's rate already (no handshake).
  std::uint32_t lms_power_up_baud = 0;
  std::optional<DeviceAddress> gps;            // serial:
  std::optional<DeviceAddress> status_led;     // gpio: an output
  std::optional<DeviceAddress> enable_switch;  // gpio: an input; mapping pauses while it is off
  bool status_led_active_low = false;          // the LED lights when the line is low
  bool enable_switch_active_low = false;       // a contact to ground with a pull-up: on = low
  double switch_debounce_s = 0.02;             // the switch is read once still this long
  // gpio: the GPS receiver's pulse-per-second (rising at each UTC second): fixes are placed on
  // its edges (hal::FixConverter::on_pps).
  std::optional<DeviceAddress> gps_pps;
  bool gps_pps_active_low = false;

  // [daemon]
  double silent_after_s = 2.0;      // a device that sends nothing this long is reopened
  double reconnect_first_s = 0.25;  // the first wait before reopening a lost device
  double reconnect_max_s = 8.0;     // waits double up to this
  double health_every_s = 1.0;      // a health record this often (health.jsonl, stderr)
  double snapshot_every_s = 10.0;   // the plane list saved this often (0: only at exit)
  int realtime_priority = 0;        // SCHED_FIFO priority of the pipeline thread; 0: normal
  bool lock_memory = false;         // mlockall() at start-up
  // The queues between the reader threads and the pipeline thread, in messages.
  std::size_t base_queue_messages = 256;  // 2.5 s of the RMP's 100 Hz groups
  std::size_t scan_queue_messages = 32;   // 0.4 s of a 75 Hz laser
  std::size_t fix_queue_messages = 16;
};

// Whether the document has a [devices] table (and so describes a robot to map from).
[[nodiscard]] bool has_devices(std::string_view text, std::string_view source);

// The [robot], [devices] and [daemon] tables. Throws ConfigError.
[[nodiscard]] DaemonConfig parse_daemon_config(std::string_view text, std::string_view source);
// A `lasers` list longer than the robot's lasers is a ConfigError naming the key.
void check_laser_count(const DaemonConfig& config, std::size_t robot_lasers,
                       std::string_view source);

[[nodiscard]] DaemonConfig load_daemon_config(const std::filesystem::path& path);
[[nodiscard]] bool file_has_devices(const std::filesystem::path& path);

}  // namespace blockmap::hal::config
