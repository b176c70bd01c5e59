// Where a device is, as the robot's configuration names it: the backend and its
// address in one string, checked before anything starts.
//   can:can0                     a SocketCAN interface (the Segway RMP)
//   serial:/dev/ttyUSB0@38400    a termios serial port at its baud rate (LMS2xx, NMEA GPS)
//   usb:19a2:5001                a USB device by vendor:product, hexadecimal (SICK TiM)
//   usb:19a2:5001:18340123       ... and its serial number, when two devices share the ids
//   gpio:gpiochip0:5             a libgpiod chip and line offset (LED, switch, PPS)
//   sim:usc_block                a simulated world (built-in name or .toml file)
//   replay:DIR                   a folder of recorded device logs
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace blockmap::hal {

enum class DeviceBackend : std::uint8_t { kCan, kSerial, kUsb, kGpio, kSim, kReplay };

[[nodiscard]] const char* to_string(DeviceBackend backend) noexcept;  // "can", "serial", ...

struct DeviceAddress {
  DeviceBackend backend = DeviceBackend::kSim;
  // The CAN interface, the tty's path, the USB serial number (empty: any), the GPIO chip, the
  // world, or the log folder.
  std::string name;
  std::uint32_t baud = 0;         // serial
  std::uint16_t vendor_id = 0;    // usb
  std::uint16_t product_id = 0;   // usb
  std::uint32_t line_offset = 0;  // gpio
};

// The address `text` names; none, with `error` set to one line that quotes the text and says
// what is wrong, when it names none.
[[nodiscard]] std::optional<DeviceAddress> parse_device_address(std::string_view text,
                                                                std::string& error);

// The string parse_device_address() reads back as the same address.
[[nodiscard]] std::string to_string(const DeviceAddress& address);

}  // namespace blockmap::hal
