#include "blockmap/hal/sim/sensor_models.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

namespace blockmap::hal::sim {
namespace {

constexpr double kRobotMassKg = 80.0;

}  // namespace

protocol::segway_rmp::StatusCycle BaseSensing::sense(const RobotState& state, double dt_s,
                                                     std::uint64_t cycle, SimRandom& random) {
  // Wheel increments as the encoders count them: scaled by the tyre pressure, with slip.
  const double true_left = state.left_wheel_m - last_true_left_m_;
  const double true_right = state.right_wheel_m - last_true_right_m_;
  last_true_left_m_ = state.left_wheel_m;
  last_true_right_m_ = state.right_wheel_m;
  const double left = true_left * (1.0 + base_.left_scale_error) +
                      random.gaussian(base_.slip_fraction * std::abs(true_left));
  const double right = true_right * (1.0 + base_.right_scale_error) +
                       random.gaussian(base_.slip_fraction * std::abs(true_right));
  left_m_ += left;
  right_m_ += right;

  protocol::segway_rmp::StatusCycle out;
  msg::OdometrySample& odometry = out.odometry;
  odometry.left_wheel_distance_m = left_m_;
  odometry.right_wheel_distance_m = right_m_;
  odometry.fore_aft_distance_m = 0.5 * (left_m_ + right_m_);
  odometry.yaw_displacement_rad = (right_m_ - left_m_) / base_.track_m;
  odometry.left_wheel_velocity_mps = left / dt_s;
  odometry.right_wheel_velocity_mps = right / dt_s;
  odometry.servo_frame_count = static_cast<std::uint16_t>(cycle & 0xFFFFU);
  msg::ImuSample& imu = out.imu;
  imu.pitch_rad = state.pitch_rad + random.gaussian(base_.pitch_noise_rad);
  imu.roll_rad = state.roll_rad + random.gaussian(base_.roll_noise_rad);
  imu.pitch_rate_radps = state.pitch_rate_radps + random.gaussian(base_.rate_noise_radps);
  imu.roll_rate_radps = state.roll_rate_radps + random.gaussian(base_.rate_noise_radps);
  imu.yaw_rate_radps = state.yaw_rate_radps + base_.yaw_rate_bias_radps +
                       random.gaussian(base_.yaw_rate_noise_radps);
  // Each motor carries half the force that accelerates the robot.
  const double torque = 0.5 * kRobotMassKg * state.accel_mps2 * base_.wheel_radius_m;
  out.left_motor_torque_nm = torque;
  out.right_motor_torque_nm = torque;
  out.status.operational_mode = 2;  // balance
  battery_v_ -= 2e-6;               // a slow drain
  out.status.powerbase_battery_v = battery_v_;
  out.status.ui_battery_v = 7.4;
  return out;
}

GpsErrorProcess::GpsErrorProcess(const config::GpsSpec& spec)
    : spec_(spec),
      // The two parts' variances add up to the horizontal RMS squared.
      slow_sigma_m_(
          std::sqrt(std::max(0.0, spec.horizontal_error_rms_m * spec.horizontal_error_rms_m -
                                      spec.multipath_error_rms_m * spec.multipath_error_rms_m) /
                    2.0)),
      multipath_sigma_m_(spec.multipath_error_rms_m / std::numbers::sqrt2) {}

void GpsErrorProcess::start(SimRandom& random) {
  // One draw per statement: the order in which a call's arguments are evaluated is
  // unspecified, and GCC and Clang differ, which made the same seed give different runs.
  // (Up, north, east: the order GCC used, so that the figures in the docs stand.)
  slow_m_.z() = random.gaussian(spec_.vertical_error_rms_m);
  slow_m_.y() = random.gaussian(slow_sigma_m_);
  slow_m_.x() = random.gaussian(slow_sigma_m_);
  multipath_m_.y() = random.gaussian(multipath_sigma_m_);
  multipath_m_.x() = random.gaussian(multipath_sigma_m_);
}

void GpsErrorProcess::advance(double dt_s, SimRandom& random) {
  const auto step = [&](double& value, double sigma, double correlation_s) {
    const double keep = std::exp(-dt_s / correlation_s);
    value = keep * value + std::sqrt(1.0 - keep * keep) * random.gaussian(sigma);
  };
  step(slow_m_.x(), slow_sigma_m_, spec_.correlation_time_s);
  step(slow_m_.y(), slow_sigma_m_, spec_.correlation_time_s);
  step(slow_m_.z(), spec_.vertical_error_rms_m, spec_.correlation_time_s);
  step(multipath_m_.x(), multipath_sigma_m_, spec_.multipath_correlation_s);
  step(multipath_m_.y(), multipath_sigma_m_, spec_.multipath_correlation_s);
}

Eigen::Vector3d GpsErrorProcess::error_m() const noexcept {
  return slow_m_ + Eigen::Vector3d(multipath_m_.x(), multipath_m_.y(), 0.0);
}

void set_fix_utc(msg::GpsFix& fix, double unix_s) noexcept {
  const auto utc_ms = static_cast<std::int64_t>(std::floor(unix_s * 1000.0 + 0.5));
  fix.has_time = true;
  fix.utc_milliseconds_of_day = static_cast<std::int32_t>(utc_ms % 86'400'000);
  const std::chrono::year_month_day date{
      std::chrono::sys_days{std::chrono::days{utc_ms / 86'400'000}}};
  fix.has_date = true;
  fix.utc_year = static_cast<std::uint16_t>(static_cast<int>(date.year()));
  fix.utc_month = static_cast<std::uint8_t>(static_cast<unsigned>(date.month()));
  fix.utc_day = static_cast<std::uint8_t>(static_cast<unsigned>(date.day()));
}

}  // namespace blockmap::hal::sim
