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
  // What a base can do, with room: a status group beyond it is a damaged one (a recorded log
  // has no CAN checksum) and is not published. The speed is a car's (the UAL loop's logs are
  // a car's motion in the RMP's frames); an RMP does 8 mph at most (docs/protocols.md 1).
  double max_speed_mps = 40.0;
  double max_rate_radps = 6.0;
  // The gyroscope's yaw rate and the wheels' ((right - left) / track) differ by slip and
  // noise, 0.2-0.6 rad/s at most in the simulated and imported runs; by more, one is damaged.
  double track_m = 0.54;
  double max_wheel_gyro_disagreement_radps = 1.0;
  double max_tilt_rad = 0.8;
  // After this many groups refused in a row the next is taken as the new start (the base's
  // integrators reset).
  std::uint32_t refusals_before_restart = 3;
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
  // Status groups no RMP could send (beyond the config's limits), not published.
  [[nodiscard]] std::uint64_t groups_implausible() const noexcept { return implausible_.value(); }

 private:
  // Whether `cycle` is within the base's limits and follows the last published one.
  [[nodiscard]] bool plausible(const protocol::segway_rmp::StatusCycle& cycle) noexcept;

  CanBus& bus_;
  SpscQueueRef<msg::OdometrySample>& odometry_;
  SpscQueueRef<msg::ImuSample>& imu_;
  SegwayBaseConfig config_;
  protocol::segway_rmp::Decoder decoder_;
  msg::DeviceStatus status_;
  MonotonicCounter published_;
  MonotonicCounter rejected_;
  MonotonicCounter implausible_;
  protocol::segway_rmp::StatusCycle last_;  // the last group published
  bool have_last_ = false;
  std::uint32_t refused_in_a_row_ = 0;
};

}  // namespace blockmap::hal::devices
