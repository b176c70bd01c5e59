// A classic CAN 2.0 frame as the HAL hands it to codecs (SocketCAN's struct can_frame without
// the kernel's bit packing).
#pragma once

#include <array>
#include <cstdint>

namespace blockmap::hal {

struct CanFrame {
  std::uint32_t id = 0;   // 11-bit (standard) or 29-bit (extended) identifier
  bool extended = false;  // 29-bit identifier
  bool remote = false;    // remote transmission request: no data
  bool error = false;     // an error frame reported by the controller
  std::uint8_t dlc = 0;   // data length, 0..8
  std::array<std::uint8_t, 8> data{};
};

}  // namespace blockmap::hal
