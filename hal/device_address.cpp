#include "blockmap/hal/device_address.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cstdio>
#include <utility>

#include "blockmap/hal/linux/serial_port.hpp"

namespace blockmap::hal {
namespace {

constexpr std::array<std::pair<DeviceBackend, std::string_view>, 6> kBackends{{
    {DeviceBackend::kCan, "can"},
    {DeviceBackend::kSerial, "serial"},
    {DeviceBackend::kUsb, "usb"},
    {DeviceBackend::kGpio, "gpio"},
    {DeviceBackend::kSim, "sim"},
    {DeviceBackend::kReplay, "replay"},
}};

// A whole unsigned number in `base`, nothing before or after it.
template <typename Number>
bool whole_number(std::string_view text, Number& value, int base = 10) {
  if (text.empty()) {
    return false;
  }
  const auto [end, problem] = std::from_chars(text.data(), text.data() + text.size(), value, base);
  return problem == std::errc{} && end == text.data() + text.size();
}

bool parse_can(std::string_view rest, DeviceAddress& address, std::string& why) {
  // Linux interface names: 1-15 characters (IFNAMSIZ 16 with the terminator), no '/' or
  // white space.
  if (rest.empty() || rest.size() > 15 || rest.find_first_of("/ \t:") != std::string_view::npos) {
    why = "a CAN interface name has 1 to 15 characters, without '/', ':' or spaces (can0, vcan0)";
    return false;
  }
  address.name = rest;
  return true;
}

bool parse_serial(std::string_view rest, DeviceAddress& address, std::string& why) {
  const std::size_t at = rest.rfind('@');
  if (rest.empty() || rest.front() != '/' || at == std::string_view::npos || at == 1) {
    why = "a serial port is a device path and its baud rate: serial:/dev/ttyUSB0@38400";
    return false;
  }
  if (!whole_number(rest.substr(at + 1), address.baud) ||
      !linux_backend::SerialPort::supported_baud(address.baud)) {
    why = "'" + std::string(rest.substr(at + 1)) +
          "' is not a baud rate termios can set (4800, 9600, 38400, 500000, ...)";
    return false;
  }
  address.name = rest.substr(0, at);
  return true;
}

bool parse_usb(std::string_view rest, DeviceAddress& address, std::string& why) {
  // VENDOR:PRODUCT, then :SERIAL when two devices share the ids (two TiMs on one robot).
  const std::size_t colon = rest.find(':');
  const std::size_t serial_colon =
      colon == std::string_view::npos ? std::string_view::npos : rest.find(':', colon + 1);
  const auto hex16 = [](std::string_view text, std::uint16_t& id) {
    return text.size() == 4 && whole_number(text, id, 16);
  };
  const std::string_view product =
      rest.substr(colon + 1, serial_colon == std::string_view::npos ? std::string_view::npos
                                                                    : serial_colon - colon - 1);
  if (colon == std::string_view::npos || !hex16(rest.substr(0, colon), address.vendor_id) ||
      !hex16(product, address.product_id)) {
    why =
        "a USB device is its vendor and product id, four hex digits each, and its serial "
        "number when two share them: usb:19a2:5001 or usb:19a2:5001:18340123";
    return false;
  }
  if (serial_colon != std::string_view::npos) {
    const std::string_view serial = rest.substr(serial_colon + 1);
    const bool printable =
        std::all_of(serial.begin(), serial.end(), [](char c) { return c > ' ' && c < 0x7f; });
    if (serial.empty() || !printable) {
      why = "a USB serial number is printable characters without spaces: usb:19a2:5001:18340123";
      return false;
    }
    address.name = serial;
  }
  return true;
}

bool parse_gpio(std::string_view rest, DeviceAddress& address, std::string& why) {
  const std::size_t colon = rest.rfind(':');
  if (colon == std::string_view::npos || colon == 0 ||
      !whole_number(rest.substr(colon + 1), address.line_offset) || address.line_offset > 1023) {
    why = "a GPIO line is a chip and a line offset: gpio:gpiochip0:5";
    return false;
  }
  address.name = rest.substr(0, colon);
  return true;
}

bool parse_named(std::string_view rest, DeviceAddress& address, std::string& why,
                 const char* what) {
  if (rest.empty()) {
    why = std::string("it needs ") + what;
    return false;
  }
  address.name = rest;
  return true;
}

}  // namespace

const char* to_string(DeviceBackend backend) noexcept {
  for (const auto& [value, name] : kBackends) {
    if (value == backend) {
      return name.data();
    }
  }
  return "unknown";
}

std::optional<DeviceAddress> parse_device_address(std::string_view text, std::string& error) {
  const std::size_t colon = text.find(':');
  const std::string_view kind = text.substr(0, colon);
  const std::string_view rest =
      colon == std::string_view::npos ? std::string_view{} : text.substr(colon + 1);
  DeviceAddress address;
  bool known = false;
  for (const auto& [backend, name] : kBackends) {
    if (colon != std::string_view::npos && kind == name) {
      address.backend = backend;
      known = true;
    }
  }
  if (!known) {
    error = "device '" + std::string(text) +
            "': starts with can:, serial:, usb:, gpio:, sim: or replay:";
    return std::nullopt;
  }
  std::string why;
  bool parsed = false;
  switch (address.backend) {
    case DeviceBackend::kCan:
      parsed = parse_can(rest, address, why);
      break;
    case DeviceBackend::kSerial:
      parsed = parse_serial(rest, address, why);
      break;
    case DeviceBackend::kUsb:
      parsed = parse_usb(rest, address, why);
      break;
    case DeviceBackend::kGpio:
      parsed = parse_gpio(rest, address, why);
      break;
    case DeviceBackend::kSim:
      parsed = parse_named(rest, address, why, "a world: sim:usc_block");
      break;
    case DeviceBackend::kReplay:
      parsed = parse_named(rest, address, why, "a folder of device logs: replay:DIR");
      break;
  }
  if (!parsed) {
    error = "device '" + std::string(text) + "': " + why;
    return std::nullopt;
  }
  return address;
}

std::string to_string(const DeviceAddress& address) {
  std::string text = std::string(to_string(address.backend)) + ':';
  switch (address.backend) {
    case DeviceBackend::kSerial:
      return text + address.name + '@' + std::to_string(address.baud);
    case DeviceBackend::kUsb: {
      char ids[16];
      std::snprintf(ids, sizeof ids, "%04x:%04x", address.vendor_id, address.product_id);
      return text + ids + (address.name.empty() ? "" : ":" + address.name);
    }
    case DeviceBackend::kGpio:
      return text + address.name + ':' + std::to_string(address.line_offset);
    case DeviceBackend::kCan:
    case DeviceBackend::kSim:
    case DeviceBackend::kReplay:
      break;
  }
  return text + address.name;
}

}  // namespace blockmap::hal
