// The simulated Segway RMP: every 10 ms the status group 0x400-0x407 (PROTOCOLS.md 1.2), with
// wheel odometry that has the tyre-pressure scale error and random slip, a yaw-rate gyro with a
// bias, and the base's own pitch and roll, all through the codec's encoder.
#include <cmath>

#include "sim_devices.hpp"

namespace blockmap::hal::sim::detail {
namespace {

constexpr TimestampNs kCycleNs = 10'000'000;  // the RMP's 100 Hz control cycle
constexpr TimestampNs kFrameGapNs = 250'000;  // an 8-byte frame at 500 kbit/s, with spacing
constexpr double kRobotMassKg = 80.0;

}  // namespace

SimRmp::SimRmp(const BaseSpec& base, std::uint64_t seed) : base_(base), random_(seed, "rmp") {
  codec_.model = base.model;
  codec_.yaw_sign = base.yaw_sign;
}

TimestampNs SimRmp::next_event_ns(const SimContext& context) const noexcept {
  if (next_frame_ < 8) {
    return frames_ns_ + static_cast<TimestampNs>(next_frame_) * kFrameGapNs;
  }
  const TimestampNs next_cycle = context.start_ns + static_cast<TimestampNs>(cycle_ + 1) * kCycleNs;
  return next_cycle > context.end_ns ? kNever : next_cycle;
}

void SimRmp::fire(SimContext& context, SimSink& sink, SimStats& stats) {
  if (next_frame_ >= 8) {
    ++cycle_;
    make_cycle(context, sink, context.start_ns + static_cast<TimestampNs>(cycle_) * kCycleNs);
    ++stats.rmp_cycles;
  }
  sink.on_can_frame(frames_ns_ + static_cast<TimestampNs>(next_frame_) * kFrameGapNs,
                    frames_.frames[next_frame_]);
  ++next_frame_;
}

void SimRmp::make_cycle(SimContext& context, SimSink& sink, TimestampNs cycle_ns) {
  const double t_s = context.seconds(cycle_ns);
  context.motion.advance_to(t_s);
  const RobotState state = context.motion.state_at(t_s);
  sink.on_truth_state(cycle_ns, state);

  // Wheel increments as the encoders count them: scaled by the tyre pressure, with slip.
  const double true_left = state.left_wheel_m - last_true_left_m_;
  const double true_right = state.right_wheel_m - last_true_right_m_;
  last_true_left_m_ = state.left_wheel_m;
  last_true_right_m_ = state.right_wheel_m;
  const double left = true_left * (1.0 + base_.left_scale_error) +
                      random_.gaussian(base_.slip_fraction * std::abs(true_left));
  const double right = true_right * (1.0 + base_.right_scale_error) +
                       random_.gaussian(base_.slip_fraction * std::abs(true_right));
  left_m_ += left;
  right_m_ += right;
  const double dt = static_cast<double>(kCycleNs) * 1e-9;

  protocol::segway_rmp::StatusCycle cycle;
  msg::OdometrySample& odometry = cycle.odometry;
  odometry.left_wheel_distance_m = left_m_;
  odometry.right_wheel_distance_m = right_m_;
  odometry.fore_aft_distance_m = 0.5 * (left_m_ + right_m_);
  odometry.yaw_displacement_rad = (right_m_ - left_m_) / base_.track_m;
  odometry.left_wheel_velocity_mps = left / dt;
  odometry.right_wheel_velocity_mps = right / dt;
  odometry.servo_frame_count = static_cast<std::uint16_t>(cycle_ & 0xFFFFU);
  msg::ImuSample& imu = cycle.imu;
  imu.pitch_rad = state.pitch_rad + random_.gaussian(base_.pitch_noise_rad);
  imu.roll_rad = state.roll_rad + random_.gaussian(base_.roll_noise_rad);
  imu.pitch_rate_radps = state.pitch_rate_radps + random_.gaussian(base_.rate_noise_radps);
  imu.roll_rate_radps = state.roll_rate_radps + random_.gaussian(base_.rate_noise_radps);
  imu.yaw_rate_radps = state.yaw_rate_radps + base_.yaw_rate_bias_radps +
                       random_.gaussian(base_.yaw_rate_noise_radps);
  // Each motor carries half the force that accelerates the robot.
  const double torque = 0.5 * kRobotMassKg * state.accel_mps2 * base_.wheel_radius_m;
  cycle.left_motor_torque_nm = torque;
  cycle.right_motor_torque_nm = torque;
  cycle.status.operational_mode = 2;  // balance
  battery_v_ -= 2e-6;                 // a slow drain
  cycle.status.powerbase_battery_v = battery_v_;
  cycle.status.ui_battery_v = 7.4;
  frames_ = protocol::segway_rmp::encode_status(cycle, codec_);
  frames_ns_ = cycle_ns;
  next_frame_ = 0;
}

}  // namespace blockmap::hal::sim::detail
