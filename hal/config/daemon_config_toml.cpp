#include "blockmap/hal/config/daemon_config.hpp"

#include "toml_reader.hpp"

namespace blockmap::hal::config {
namespace {

// The device string under `key`, which must use one of `allowed` backends (what that device
// can be reached through); none when the key is absent.
std::optional<DeviceAddress> device_at(TableReader& table, std::string_view key,
                                       std::initializer_list<DeviceBackend> allowed,
                                       std::string_view what) {
  if (!table.has(key)) {
    static_cast<void>(table.string_or(key, ""));
    return std::nullopt;
  }
  const std::string text = table.string(key);
  std::string error;
  std::optional<DeviceAddress> address = parse_device_address(text, error);
  if (!address) {
    table.fail(key, error);
  }
  for (const DeviceBackend backend : allowed) {
    if (address->backend == backend) {
      return address;
    }
  }
  table.fail(key, "\"" + text + "\": " + std::string(what));
}

void read_devices(TableReader& t, DaemonConfig& c) {
  if (t.has("robot")) {
    c.whole_robot = device_at(t, "robot", {DeviceBackend::kSim, DeviceBackend::kReplay},
                              "the whole robot is sim:WORLD or replay:DIR");
    for (const char* key : {"base", "lasers", "gps"}) {
      if (t.has(key)) {
        t.fail(key, "not with robot = \"" + to_string(*c.whole_robot) +
                        "\": the simulated or replayed robot brings its own devices");
      }
    }
  }
  c.base = device_at(t, "base", {DeviceBackend::kCan}, "the Segway RMP is on a CAN bus (can:can0)");
  const std::vector<std::string> lasers = t.string_list_or_empty("lasers");
  for (std::size_t i = 0; i < lasers.size(); ++i) {
    const std::string key = "lasers[" + std::to_string(i) + "]";
    if (lasers[i].empty()) {
      c.lasers.emplace_back();  // "": this laser is not attached
      continue;
    }
    std::string error;
    std::optional<DeviceAddress> address = parse_device_address(lasers[i], error);
    if (!address) {
      t.fail(key, error);
    }
    if (address->backend != DeviceBackend::kSerial && address->backend != DeviceBackend::kUsb) {
      t.fail(key, "\"" + lasers[i] +
                      "\": an LMS2xx is on a serial line (serial:/dev/ttyUSB0@500000), a TiM on "
                      "USB (usb:19a2:5001)");
    }
    for (const std::optional<DeviceAddress>& other : c.lasers) {
      if (other && other->backend == DeviceBackend::kUsb &&
          address->backend == DeviceBackend::kUsb && other->vendor_id == address->vendor_id &&
          other->product_id == address->product_id &&
          (other->name.empty() || address->name.empty() || other->name == address->name)) {
        t.fail(key, "\"" + lasers[i] +
                        "\": two lasers with the same ids are told apart by their serial "
                        "numbers (usb:19a2:5001:SERIAL)");
      }
    }
    c.lasers.push_back(address);
  }
  const std::int64_t power_up = t.integer_or("lms_power_up_baud", c.lms_power_up_baud);
  if (power_up != 0 && power_up != 9600 && power_up != 19200 && power_up != 38400 &&
      power_up != 500000) {
    t.fail("lms_power_up_baud",
           "an LMS2xx talks at 9600, 19200, 38400 or 500000 Bd (0: no "
           "handshake)");
  }
  c.lms_power_up_baud = static_cast<std::uint32_t>(power_up);
  c.gps = device_at(t, "gps", {DeviceBackend::kSerial},
                    "an NMEA receiver is on a serial line (serial:/dev/ttyUSB2@9600)");
  c.status_led = device_at(t, "status_led", {DeviceBackend::kGpio},
                           "an LED is a GPIO line (gpio:gpiochip0:5)");
  c.enable_switch = device_at(t, "enable_switch", {DeviceBackend::kGpio},
                              "a switch is a GPIO line (gpio:gpiochip0:6)");
  c.gps_pps = device_at(t, "gps_pps", {DeviceBackend::kGpio},
                        "a PPS output is a GPIO line (gpio:gpiochip0:4)");
  c.gps_pps_active_low = t.boolean_or("gps_pps_active_low", c.gps_pps_active_low);
  c.status_led_active_low = t.boolean_or("status_led_active_low", c.status_led_active_low);
  c.enable_switch_active_low = t.boolean_or("enable_switch_active_low", c.enable_switch_active_low);
  c.switch_debounce_s = t.in_range("switch_debounce_s",
                                   t.number_or("switch_debounce_s", c.switch_debounce_s), 0.0, 1.0);
  const auto same_line = [](const std::optional<DeviceAddress>& a,
                            const std::optional<DeviceAddress>& b) {
    return a && b && a->name == b->name && a->line_offset == b->line_offset;
  };
  if (same_line(c.status_led, c.enable_switch)) {
    t.fail("enable_switch", "is the status LED's line");
  }
  if (same_line(c.gps_pps, c.status_led) || same_line(c.gps_pps, c.enable_switch)) {
    t.fail("gps_pps", "is the status LED's or the enable switch's line");
  }
  if (!c.whole_robot && !c.base && !c.gps) {
    t.fail("base", "a robot needs its base (can:...) or a GPS (serial:...) to know where it is");
  }
  t.finish();
}

void read_daemon(TableReader& t, DaemonConfig& c) {
  c.silent_after_s = t.positive_or("silent_after_s", c.silent_after_s);
  c.reconnect_first_s = t.positive_or("reconnect_first_s", c.reconnect_first_s);
  c.reconnect_max_s = t.positive_or("reconnect_max_s", c.reconnect_max_s);
  if (c.reconnect_max_s < c.reconnect_first_s) {
    t.fail("reconnect_max_s", "must be at least reconnect_first_s");
  }
  c.health_every_s = t.positive_or("health_every_s", c.health_every_s);
  c.snapshot_every_s = t.non_negative_or("snapshot_every_s", c.snapshot_every_s);
  c.realtime_priority = static_cast<int>(t.in_range(
      "realtime_priority",
      static_cast<double>(t.integer_or("realtime_priority", c.realtime_priority)), 0.0, 99.0));
  c.lock_memory = t.boolean_or("lock_memory", c.lock_memory);
  c.base_queue_messages = t.capacity_or("base_queue_messages", c.base_queue_messages);
  c.scan_queue_messages = t.capacity_or("scan_queue_messages", c.scan_queue_messages);
  c.fix_queue_messages = t.capacity_or("fix_queue_messages", c.fix_queue_messages);
  t.finish();
}

}  // namespace

bool has_devices(std::string_view text, std::string_view source) {
  const toml::table document = parse_document(text, source);
  return document.contains("devices");
}

DaemonConfig parse_daemon_config(std::string_view text, std::string_view source) {
  const toml::table document = parse_document(text, source);
  refuse_unknown_tables(document, source);
  TableReader root(document, std::string(source), "");
  DaemonConfig c;
  if (auto table = root.table("robot")) {
    c.robot = table->string("spec");
    table->finish();
  }
  auto devices = root.table("devices");
  if (!devices) {
    throw ConfigError(std::string(source) + ": no [devices] table: nothing to map from");
  }
  read_devices(*devices, c);
  if (auto table = root.table("daemon")) {
    read_daemon(*table, c);
  }
  return c;
}

void check_laser_count(const DaemonConfig& config, std::size_t robot_lasers,
                       std::string_view source) {
  if (config.lasers.size() > robot_lasers) {
    throw ConfigError(
        std::string(source) + ": devices.lasers: " + std::to_string(config.lasers.size()) +
        " devices for the robot's " + std::to_string(robot_lasers) + " lasers ([robot] spec)");
  }
}

DaemonConfig load_daemon_config(const std::filesystem::path& path) {
  return parse_daemon_config(read_config_file(path), path.string());
}

bool file_has_devices(const std::filesystem::path& path) {
  return has_devices(read_config_file(path), path.string());
}

}  // namespace blockmap::hal::config
