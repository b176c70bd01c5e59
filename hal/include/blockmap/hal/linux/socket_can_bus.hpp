// SocketCanBus: the CanBus port on a Linux SocketCAN interface (can0 on the robot's USB-CAN or
// on-board controller, vcan0 in tests), for the Segway RMP.
//
// A raw CAN socket, non-blocking, waited on with poll() for at most the caller's timeout.
// Every error class is asked for (CAN_RAW_ERR_FILTER), so that the controller's error frames
// reach the caller, who counts them; bus-off reads as kDeviceLost, and so does the interface
// going down. Frames are stamped with the kernel's receive time (SO_TIMESTAMPNS), moved from
// the realtime clock it is taken on to CLOCK_MONOTONIC, the base of every stamp here.
#pragma once

#include <cstdint>
#include <string>

#include "blockmap/hal/can_bus.hpp"

namespace blockmap::hal::linux_backend {

class SocketCanBus final : public CanBus {
 public:
  // The most acceptance filters set_filters() takes (the RMP needs four).
  static constexpr std::size_t kMaxFilters = 16;

  SocketCanBus() = default;
  ~SocketCanBus() override;

  // Binds to `interface` (can0, vcan0). Empty when it worked, otherwise one line naming the
  // interface and the reason. Closes a socket already open first.
  [[nodiscard]] std::string open(const std::string& interface);
  void close() noexcept;
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }
  [[nodiscard]] const std::string& interface() const noexcept { return interface_; }
  // Bus-off reports among the error frames received (each is also a kDeviceLost).
  [[nodiscard]] std::uint64_t bus_off_count() const noexcept { return bus_off_; }

 protected:
  CanReceiveResult do_receive(CanFrame& frame, TimestampNs timeout_ns) override;
  IoStatus do_send(const CanFrame& frame) override;
  IoStatus do_set_filters(std::span<const CanFilter> filters) override;

 private:
  int fd_ = -1;
  std::string interface_;
  std::uint64_t bus_off_ = 0;
};

}  // namespace blockmap::hal::linux_backend
