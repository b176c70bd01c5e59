// Device strings of the robot's configuration: every backend's form, read back the
// same, and one clear line for each mistake.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "blockmap/hal/device_address.hpp"

namespace blockmap::hal {
namespace {

DeviceAddress parsed(const std::string& text) {
  std::string error;
  const std::optional<DeviceAddress> address = parse_device_address(text, error);
  EXPECT_TRUE(address.has_value()) << text << ": " << error;
  return address.value_or(DeviceAddress{});
}

TEST(DeviceAddress, ReadsEveryBackendsForm) {
  DeviceAddress a = parsed("can:can0");
  EXPECT_EQ(a.backend, DeviceBackend::kCan);
  EXPECT_EQ(a.name, "can0");

  a = parsed("serial:/dev/ttyUSB0@38400");
  EXPECT_EQ(a.backend, DeviceBackend::kSerial);
  EXPECT_EQ(a.name, "/dev/ttyUSB0");
  EXPECT_EQ(a.baud, 38400u);
  EXPECT_EQ(parsed("serial:/dev/serial/by-id/usb-FTDI@x-if00@500000").name,
            "/dev/serial/by-id/usb-FTDI@x-if00");  // the last '@' is the rate's

  a = parsed("usb:19a2:5001");
  EXPECT_EQ(a.backend, DeviceBackend::kUsb);
  EXPECT_EQ(a.vendor_id, 0x19a2);
  EXPECT_EQ(a.product_id, 0x5001);
  EXPECT_EQ(a.name, "") << "any serial number";
  a = parsed("usb:19a2:5001:18340123");
  EXPECT_EQ(a.product_id, 0x5001);
  EXPECT_EQ(a.name, "18340123");

  a = parsed("gpio:gpiochip0:5");
  EXPECT_EQ(a.backend, DeviceBackend::kGpio);
  EXPECT_EQ(a.name, "gpiochip0");
  EXPECT_EQ(a.line_offset, 5u);

  a = parsed("sim:usc_block");
  EXPECT_EQ(a.backend, DeviceBackend::kSim);
  EXPECT_EQ(a.name, "usc_block");

  a = parsed("replay:/var/log/blockmap/run-3");
  EXPECT_EQ(a.backend, DeviceBackend::kReplay);
  EXPECT_EQ(a.name, "/var/log/blockmap/run-3");
}

TEST(DeviceAddress, WritesWhatItReads) {
  for (const std::string text :
       {"can:vcan0", "serial:/dev/ttyS1@500000", "usb:19a2:5001", "usb:15d1:0000",
        "usb:19a2:5001:A1b2-C3", "gpio:gpiochip2:17", "sim:benning", "replay:logs"}) {
    EXPECT_EQ(to_string(parsed(text)), text);
  }
}

TEST(DeviceAddress, EveryMistakeIsOneLineQuotingTheString) {
  const std::vector<std::pair<std::string, std::string>> mistakes = {
      {"/dev/ttyUSB0", "starts with can:, serial:"},
      {"spi:0", "starts with can:, serial:"},
      {"can:", "1 to 15 characters"},
      {"can:a_very_long_interface", "1 to 15 characters"},
      {"serial:/dev/ttyUSB0", "device path and its baud rate"},
      {"serial:ttyUSB0@9600", "device path and its baud rate"},
      {"serial:/dev/ttyUSB0@38401", "'38401' is not a baud rate"},
      {"serial:/dev/ttyUSB0@fast", "'fast' is not a baud rate"},
      {"usb:19a2", "four hex digits each"},
      {"usb:19a2:50011", "four hex digits each"},
      {"usb:19g2:5001", "four hex digits each"},
      {"usb:19a2:5001:", "serial number is printable characters"},
      {"usb:19a2:5001:18 34", "serial number is printable characters"},
      {"gpio:gpiochip0", "a chip and a line offset"},
      {"gpio:gpiochip0:-1", "a chip and a line offset"},
      {"gpio::5", "a chip and a line offset"},
      {"sim:", "needs a world"},
      {"replay:", "needs a folder"},
  };
  for (const auto& [text, expected] : mistakes) {
    std::string error;
    EXPECT_FALSE(parse_device_address(text, error).has_value()) << text;
    EXPECT_NE(error.find("device '" + text + "'"), std::string::npos) << error;
    EXPECT_NE(error.find(expected), std::string::npos) << text << " -> " << error;
    EXPECT_EQ(error.find('\n'), std::string::npos);
  }
}

}  // namespace
}  // namespace blockmap::hal
