// The health of a device as it reports it (not the link's health, which the HAL counts).
#pragma once

#include <cstdint>

#include "blockmap/msg/header.hpp"

namespace blockmap::msg {

enum class DeviceSeverity : std::uint8_t { kOk = 0, kInfo, kWarning, kError, kFatal };

struct DeviceStatus {
  Header header;
  DeviceSeverity severity = DeviceSeverity::kOk;
  std::uint32_t device_code = 0;  // the device's own status word, for logs
  // Segway RMP: operational mode (0 disabled, 1 tractor, 2 balance, 3 power-down), battery.
  std::uint8_t operational_mode = 0;
  double ui_battery_v = 0.0;
  double powerbase_battery_v = 0.0;
  bool motors_enabled = false;
};

}  // namespace blockmap::msg
