// SegwayBase: a Segway RMP on a CanBus. Each poll() drains the frames the bus has and publishes
// one odometry and one IMU sample per complete status group into the runtime's queues. The base
// is only listened to: no command is sent (docs/protocols.md 1.7: a host that commands must keep
// sending every 10-300 ms, which is not the mapper's job).
#pragma once

#include <cstdint>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/can_bus.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/msg/device_status.hpp"
#include "blockmap/msg/odometry.hpp"

namespace blockmap::hal::devices {

struct SegwayBaseConfig {
  protocol::segway_rmp::Config rmp;
  std::size_t max_frames_per_poll = 64;  // bounds one poll's work (8 frames per 10 ms group)
};

class SegwayBase {
 public:
  SegwayBase(CanBus& bus, SpscQueueRef<msg::OdometrySample>& odometry,
             SpscQueueRef<msg::ImuSample>& imu, const SegwayBaseConfig& config);

  // Installs the acceptance filters for the RMP's status group and CU status (0x400-0x407,
  // 0x680), so the socket never wakes the reader for other traffic.
  IoStatus install_filters();
  // Receives up to max_frames_per_poll frames (waiting at most timeout_ns for the first).
  // Returns kOk when frames came, else the bus's status (kDeviceLost: bus-off).
  IoStatus poll(TimestampNs timeout_ns);

  [[nodiscard]] const protocol::segway_rmp::Decoder& decoder() const noexcept { return decoder_; }
  [[nodiscard]] const msg::DeviceStatus& status() const noexcept { return status_; }
  [[nodiscard]] std::uint64_t samples_published() const noexcept { return published_.value(); }
  [[nodiscard]] std::uint64_t samples_rejected() const noexcept { return rejected_.value(); }

 private:
  CanBus& bus_;
  SpscQueueRef<msg::OdometrySample>& odometry_;
  SpscQueueRef<msg::ImuSample>& imu_;
  SegwayBaseConfig config_;
  protocol::segway_rmp::Decoder decoder_;
  msg::DeviceStatus status_;
  MonotonicCounter published_;
  MonotonicCounter rejected_;
};

}  // namespace blockmap::hal::devices
