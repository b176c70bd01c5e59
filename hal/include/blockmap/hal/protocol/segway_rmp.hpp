// Segway RMP codec (classic RMP 50/100/200/400 CAN interface; docs/protocols.md section 1).
//
// The base sends a group of status frames 0x400..0x407 every 10 ms. The decoder reads each
// frame and, when 0x407 closes a group that held every frame 0x401..0x406, hands out one
// StatusCycle: odometry, IMU and device status in SI units, stamped with the receive time of the
// group's first frame. Pure: no sockets, no clock, no heap. The command (0x413) and shutdown
// (0x412) encoders exist for tests and a simulated base; the mapper only listens.
#pragma once

#include <cstdint>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/can_frame.hpp"
#include "blockmap/hal/protocol/drop_counters.hpp"
#include "blockmap/msg/device_status.hpp"
#include "blockmap/msg/odometry.hpp"

namespace blockmap::hal::protocol::segway_rmp {

// CAN identifiers (docs/protocols.md 1.2).
inline constexpr std::uint32_t kStatusFirstId = 0x400;  // cycle start; payload unverified
inline constexpr std::uint32_t kStatusLastId = 0x407;   // cycle end
inline constexpr std::uint32_t kShutdownId = 0x412;
inline constexpr std::uint32_t kCommandId = 0x413;
inline constexpr std::uint32_t kCuStatusId = 0x680;

enum class Model : std::uint8_t { kRmp50, kRmp100, kRmp200, kRmp400 };

// Counts per SI unit (docs/protocols.md 1.5). RMP 400 = two RMP 200 power bases.
struct ScaleFactors {
  double counts_per_deg = 7.8;       // pitch, roll and their rates, yaw rate (per deg/s)
  double counts_per_mps = 332.0;     // wheel velocity
  double counts_per_m = 33215.0;     // integrated distances
  double counts_per_rev = 112644.0;  // integrated yaw
  double counts_per_nm = 1094.0;     // motor torque
  double seconds_per_servo_frame = 0.01;
};
[[nodiscard]] ScaleFactors scale_factors(Model model) noexcept;

enum class DropReason : std::uint8_t {
  kBadLength,        // DLC other than 8
  kNotStandard,      // extended, remote or error frame on the RMP's bus
  kForeignId,        // a frame of another node (UI heartbeat, 0x412 from the UI, ...)
  kIncompleteCycle,  // 0x407 arrived but frames of the group were missing (lost on the bus)
  kDuplicate,        // the same status frame twice in a row (a retransmission), ignored
  kCount
};
[[nodiscard]] const char* to_string(DropReason reason) noexcept;

struct Config {
  Model model = Model::kRmp200;
  msg::SourceId source_id = 0;
  // The RMP's yaw sign convention is unverified (docs/protocols.md 1.8): +1 keeps the frames' sign,
  // -1 flips yaw rate and integrated yaw so that counter-clockwise is positive on this robot.
  int yaw_sign = 1;
};

// Everything one status group says.
struct StatusCycle {
  msg::OdometrySample odometry;
  msg::ImuSample imu;
  msg::DeviceStatus status;
  std::uint8_t gain_schedule = 0;  // 0 light, 1 tall, 2 heavy
  double left_motor_torque_nm = 0.0;
  double right_motor_torque_nm = 0.0;
  std::int16_t velocity_command_counts = 0;  // echo of the last 0x413 the base obeyed
  std::int16_t turn_command_counts = 0;
};

class Decoder {
 public:
  explicit Decoder(const Config& config = {});

  enum class FrameKind : std::uint8_t { kStatus, kCuStatus, kIgnored, kRejected };
  struct Step {
    FrameKind kind = FrameKind::kIgnored;
    DropReason reason = DropReason::kForeignId;  // when kRejected or kIgnored
    const StatusCycle* cycle = nullptr;          // set when this frame completed a group
  };

  // Reads one frame. O(1), never allocates.
  Step push(const CanFrame& frame, TimestampNs rx_stamp_ns);

  // The values of the most recent frames, complete group or not (for `blockmap decode rmp`).
  [[nodiscard]] const StatusCycle& latest() const noexcept { return latest_; }
  [[nodiscard]] const DropCounters<DropReason>& drops() const noexcept { return drops_; }
  [[nodiscard]] std::uint64_t cycles_decoded() const noexcept { return cycles_.value(); }

 private:
  void read_status(const CanFrame& frame);

  Config config_;
  ScaleFactors scale_;
  StatusCycle latest_;
  StatusCycle completed_;
  std::uint8_t seen_mask_ = 0;      // bit n: frame 0x400 + n seen in the current group
  std::uint8_t last_index_ = 0xFF;  // the previous status frame's id - 0x400
  TimestampNs cycle_stamp_ns_ = 0;
  DropCounters<DropReason> drops_;
  MonotonicCounter cycles_;
};

// --- encoders (host -> RMP, and a simulated base's status frames)

// 0x413: velocity and turn demand in counts (clamped to the limits of docs/protocols.md 1.6), with
// an optional configuration command (id 0 = none) and parameter.
[[nodiscard]] CanFrame encode_command(std::int16_t velocity_counts, std::int16_t turn_counts,
                                      std::uint16_t config_id = 0,
                                      std::uint16_t config_value = 0) noexcept;
// 0x412 with zero data: powers the base down. Never sent by the mapper.
[[nodiscard]] CanFrame encode_shutdown() noexcept;

// The eight status frames 0x400..0x407 a base would send for `cycle` (SI values rounded to
// counts with `model`'s scale factors and `yaw_sign`).
struct StatusFrames {
  CanFrame frames[8];
};
[[nodiscard]] StatusFrames encode_status(const StatusCycle& cycle, const Config& config) noexcept;

}  // namespace blockmap::hal::protocol::segway_rmp
