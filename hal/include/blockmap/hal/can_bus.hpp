// CanBus port: Linux SocketCAN on the robot, a loopback bus in simulation.
#pragma once

#include <cstdint>
#include <span>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/status.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/hal/can_frame.hpp"

namespace blockmap::hal {

// Accept a frame when (frame.id & mask) == (id & mask), as SocketCAN's CAN_RAW_FILTER does.
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0;
};

struct CanReceiveResult {
  IoStatus status = IoStatus::kWouldBlock;
  TimestampNs stamp_ns = 0;  // the kernel's (or simulation's) receive time
};

class CanBus {
 public:
  CanBus() = default;
  CanBus(const CanBus&) = delete;
  CanBus& operator=(const CanBus&) = delete;
  virtual ~CanBus() = default;

  // Waits at most timeout_ns for one frame. Error frames are delivered with frame.error set so
  // that the caller can count them; kDeviceLost means the controller went bus-off.
  CanReceiveResult receive(CanFrame& frame, TimestampNs timeout_ns);
  IoStatus send(const CanFrame& frame);
  // Replaces the acceptance filters (empty: accept everything).
  IoStatus set_filters(std::span<const CanFilter> filters);

  [[nodiscard]] std::uint64_t frames_received() const noexcept { return received_.value(); }
  [[nodiscard]] std::uint64_t frames_sent() const noexcept { return sent_.value(); }
  [[nodiscard]] std::uint64_t error_frames() const noexcept { return error_frames_.value(); }
  [[nodiscard]] std::uint64_t failures() const noexcept { return failures_.value(); }

 protected:
  virtual CanReceiveResult do_receive(CanFrame& frame, TimestampNs timeout_ns) = 0;
  virtual IoStatus do_send(const CanFrame& frame) = 0;
  virtual IoStatus do_set_filters(std::span<const CanFilter> filters) = 0;

 private:
  MonotonicCounter received_;
  MonotonicCounter sent_;
  MonotonicCounter error_frames_;
  MonotonicCounter failures_;
};

}  // namespace blockmap::hal
