// Segway RMP status frames (docs/protocols.md 1.3-1.5): 16-bit fields big-endian, 32-bit fields
// low word first with each word big-endian.
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/core/angles.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "blockmap/core/check.hpp"

namespace blockmap::hal::protocol::segway_rmp {
namespace {

constexpr std::uint8_t kAllStatusFrames = 0x7E;  // 0x401..0x406

// Slot n = bytes 2n..2n+1, big-endian (docs/protocols.md 1.3).
std::uint16_t u16(const CanFrame& frame, std::size_t slot) noexcept {
  return static_cast<std::uint16_t>((frame.data[2 * slot] << 8) | frame.data[2 * slot + 1]);
}
std::int16_t s16(const CanFrame& frame, std::size_t slot) noexcept {
  return static_cast<std::int16_t>(u16(frame, slot));
}
// 32-bit value in bytes 4h..4h+3: low 16-bit word first, each word big-endian.
std::int32_t s32(const CanFrame& frame, std::size_t half) noexcept {
  const std::uint32_t low = u16(frame, 2 * half);
  const std::uint32_t high = u16(frame, 2 * half + 1);
  return static_cast<std::int32_t>((high << 16) | low);
}

void put_u16(CanFrame& frame, std::size_t slot, std::uint16_t value) noexcept {
  frame.data[2 * slot] = static_cast<std::uint8_t>(value >> 8);
  frame.data[2 * slot + 1] = static_cast<std::uint8_t>(value & 0xFF);
}
void put_s16(CanFrame& frame, std::size_t slot, double counts) noexcept {
  const double clamped = std::clamp(std::round(counts), -32768.0, 32767.0);
  put_u16(frame, slot, static_cast<std::uint16_t>(static_cast<std::int16_t>(clamped)));
}
void put_s32(CanFrame& frame, std::size_t half, double counts) noexcept {
  const double clamped = std::clamp(std::round(counts), -2147483648.0, 2147483647.0);
  const auto value = static_cast<std::uint32_t>(static_cast<std::int32_t>(clamped));
  put_u16(frame, 2 * half, static_cast<std::uint16_t>(value & 0xFFFF));
  put_u16(frame, 2 * half + 1, static_cast<std::uint16_t>(value >> 16));
}

CanFrame make_frame(std::uint32_t id) noexcept {
  CanFrame frame;
  frame.id = id;
  frame.dlc = 8;
  return frame;
}

double degrees_counts_to_rad(std::int16_t counts, const ScaleFactors& scale) noexcept {
  return counts / scale.counts_per_deg * kRadiansPerDegree;
}

}  // namespace

ScaleFactors scale_factors(Model model) noexcept {
  ScaleFactors scale;
  if (model == Model::kRmp50 || model == Model::kRmp100) {
    scale.counts_per_mps = 401.0;  // [single] libsegwayrmp
    scale.counts_per_m = 40181.0;
    scale.counts_per_rev = 117031.0;
    scale.counts_per_nm = 1463.0;
  }
  return scale;
}

const char* to_string(DropReason reason) noexcept {
  switch (reason) {
    case DropReason::kBadLength:
      return "bad_length";
    case DropReason::kNotStandard:
      return "not_standard";
    case DropReason::kForeignId:
      return "foreign_id";
    case DropReason::kIncompleteCycle:
      return "incomplete_cycle";
    case DropReason::kDuplicate:
      return "duplicate";
    case DropReason::kCount:
      break;
  }
  return "?";
}

Decoder::Decoder(const Config& config) : config_(config), scale_(scale_factors(config.model)) {
  BLOCKMAP_CHECK_MSG(config.yaw_sign == 1 || config.yaw_sign == -1,
                     "RMP yaw_sign must be +1 or -1");
}

Decoder::Step Decoder::push(const CanFrame& frame, TimestampNs rx_stamp_ns) {
  Step step;
  if (frame.extended || frame.remote || frame.error) {
    drops_.count(DropReason::kNotStandard);
    step.kind = FrameKind::kRejected;
    step.reason = DropReason::kNotStandard;
    return step;
  }
  const bool status = frame.id >= kStatusFirstId && frame.id <= kStatusLastId;
  if (!status && frame.id != kCuStatusId) {
    drops_.count(DropReason::kForeignId);
    return step;  // kIgnored: other nodes' traffic is normal on this bus
  }
  if (frame.dlc != 8) {
    drops_.count(DropReason::kBadLength);
    step.kind = FrameKind::kRejected;
    step.reason = DropReason::kBadLength;
    return step;
  }
  if (frame.id == kCuStatusId) {
    // Motors enabled: CU status word 1 bit 0x0080 (docs/protocols.md 1.4; mask the bit).
    latest_.status.motors_enabled = (u16(frame, 1) & 0x0080U) != 0;
    step.kind = FrameKind::kCuStatus;
    return step;
  }

  const auto index = static_cast<std::uint8_t>(frame.id - kStatusFirstId);
  if (index == last_index_) {  // a retransmitted frame: the group already has it
    drops_.count(DropReason::kDuplicate);
    step.reason = DropReason::kDuplicate;
    return step;  // kIgnored
  }
  last_index_ = index;
  step.kind = FrameKind::kStatus;
  if (index == 0 || seen_mask_ == 0) {  // a new group starts
    seen_mask_ = 0;
    cycle_stamp_ns_ = rx_stamp_ns;
  }
  seen_mask_ = static_cast<std::uint8_t>(seen_mask_ | (1U << index));
  read_status(frame);
  if (frame.id == kStatusLastId) {
    if ((seen_mask_ & kAllStatusFrames) == kAllStatusFrames) {
      completed_ = latest_;
      const msg::Header header{cycle_stamp_ns_, config_.source_id};
      completed_.odometry.header = header;
      completed_.imu.header = header;
      completed_.status.header = header;
      cycles_.increment();
      step.cycle = &completed_;
    } else {
      drops_.count(DropReason::kIncompleteCycle);
    }
    seen_mask_ = 0;
  }
  return step;
}

// One status frame into the latest values (docs/protocols.md 1.4 layouts, 1.5 scales).
void Decoder::read_status(const CanFrame& frame) {
  const double yaw_sign = config_.yaw_sign;
  switch (frame.id) {
    case 0x401:
      latest_.imu.pitch_rad = degrees_counts_to_rad(s16(frame, 0), scale_);
      latest_.imu.pitch_rate_radps = degrees_counts_to_rad(s16(frame, 1), scale_);
      latest_.imu.roll_rad = degrees_counts_to_rad(s16(frame, 2), scale_);
      latest_.imu.roll_rate_radps = degrees_counts_to_rad(s16(frame, 3), scale_);
      break;
    case 0x402:
      latest_.odometry.left_wheel_velocity_mps = s16(frame, 0) / scale_.counts_per_mps;
      latest_.odometry.right_wheel_velocity_mps = s16(frame, 1) / scale_.counts_per_mps;
      latest_.imu.yaw_rate_radps = yaw_sign * degrees_counts_to_rad(s16(frame, 2), scale_);
      latest_.odometry.servo_frame_count = u16(frame, 3);
      break;
    case 0x403:
      latest_.odometry.left_wheel_distance_m = s32(frame, 0) / scale_.counts_per_m;
      latest_.odometry.right_wheel_distance_m = s32(frame, 1) / scale_.counts_per_m;
      break;
    case 0x404:
      latest_.odometry.fore_aft_distance_m = s32(frame, 0) / scale_.counts_per_m;
      latest_.odometry.yaw_displacement_rad =
          yaw_sign * s32(frame, 1) / scale_.counts_per_rev * 2.0 * std::numbers::pi;
      break;
    case 0x405:
      latest_.left_motor_torque_nm = s16(frame, 0) / scale_.counts_per_nm;
      latest_.right_motor_torque_nm = s16(frame, 1) / scale_.counts_per_nm;
      break;
    case 0x406:
      latest_.status.operational_mode = static_cast<std::uint8_t>(u16(frame, 0));
      latest_.gain_schedule = static_cast<std::uint8_t>(u16(frame, 1));
      latest_.status.ui_battery_v = 1.4 + 0.0125 * u16(frame, 2);
      latest_.status.powerbase_battery_v = u16(frame, 3) / 4.0;
      latest_.status.device_code = u16(frame, 0);
      break;
    case 0x407:
      latest_.velocity_command_counts = s16(frame, 0);
      latest_.turn_command_counts = s16(frame, 1);
      break;
    default:  // 0x400: cycle start marker, payload unverified (docs/protocols.md 1.9)
      break;
  }
}

CanFrame encode_command(std::int16_t velocity_counts, std::int16_t turn_counts,
                        std::uint16_t config_id, std::uint16_t config_value) noexcept {
  // Limits: +-1176 counts velocity ("8 mph"), +-1024 turn (docs/protocols.md 1.6).
  CanFrame frame = make_frame(kCommandId);
  put_s16(frame, 0, std::clamp<double>(velocity_counts, -1176.0, 1176.0));
  put_s16(frame, 1, std::clamp<double>(turn_counts, -1024.0, 1024.0));
  put_u16(frame, 2, config_id);
  put_u16(frame, 3, config_value);  // "00 vv" for values < 256, as libsegwayrmp and CARMEN send
  return frame;
}

CanFrame encode_shutdown() noexcept {
  return make_frame(kShutdownId);
}

StatusFrames encode_status(const StatusCycle& cycle, const Config& config) noexcept {
  const ScaleFactors scale = scale_factors(config.model);
  const double yaw_sign = config.yaw_sign;
  const double counts_per_rad = scale.counts_per_deg / kRadiansPerDegree;
  StatusFrames out;
  for (std::uint32_t i = 0; i < 8; ++i) {
    out.frames[i] = make_frame(kStatusFirstId + i);
  }
  CanFrame* f = out.frames;
  put_s16(f[1], 0, cycle.imu.pitch_rad * counts_per_rad);
  put_s16(f[1], 1, cycle.imu.pitch_rate_radps * counts_per_rad);
  put_s16(f[1], 2, cycle.imu.roll_rad * counts_per_rad);
  put_s16(f[1], 3, cycle.imu.roll_rate_radps * counts_per_rad);
  put_s16(f[2], 0, cycle.odometry.left_wheel_velocity_mps * scale.counts_per_mps);
  put_s16(f[2], 1, cycle.odometry.right_wheel_velocity_mps * scale.counts_per_mps);
  put_s16(f[2], 2, yaw_sign * cycle.imu.yaw_rate_radps * counts_per_rad);
  put_u16(f[2], 3, cycle.odometry.servo_frame_count);
  put_s32(f[3], 0, cycle.odometry.left_wheel_distance_m * scale.counts_per_m);
  put_s32(f[3], 1, cycle.odometry.right_wheel_distance_m * scale.counts_per_m);
  put_s32(f[4], 0, cycle.odometry.fore_aft_distance_m * scale.counts_per_m);
  put_s32(f[4], 1,
          yaw_sign * cycle.odometry.yaw_displacement_rad / (2.0 * std::numbers::pi) *
              scale.counts_per_rev);
  put_s16(f[5], 0, cycle.left_motor_torque_nm * scale.counts_per_nm);
  put_s16(f[5], 1, cycle.right_motor_torque_nm * scale.counts_per_nm);
  put_u16(f[6], 0, cycle.status.operational_mode);
  put_u16(f[6], 1, cycle.gain_schedule);
  put_u16(f[6], 2,
          static_cast<std::uint16_t>(
              std::lround(std::max(0.0, (cycle.status.ui_battery_v - 1.4) / 0.0125))));
  put_u16(f[6], 3,
          static_cast<std::uint16_t>(
              std::lround(std::max(0.0, cycle.status.powerbase_battery_v * 4.0))));
  put_s16(f[7], 0, cycle.velocity_command_counts);
  put_s16(f[7], 1, cycle.turn_command_counts);
  return out;
}

}  // namespace blockmap::hal::protocol::segway_rmp
