// Wheel odometry and inertial sensing as a Segway RMP reports them, in SI units.
#pragma once

#include <cstdint>

#include "blockmap/msg/header.hpp"

namespace blockmap::msg {

// Integrated quantities are as the base counts them since its integrators were last reset;
// the localizer differences consecutive samples. Signs: forward motion positive, yaw
// counter-clockwise (seen from above) positive after the device layer's configured sign.
struct OdometrySample {
  Header header;
  double left_wheel_distance_m = 0.0;
  double right_wheel_distance_m = 0.0;
  double fore_aft_distance_m = 0.0;
  double yaw_displacement_rad = 0.0;
  double left_wheel_velocity_mps = 0.0;
  double right_wheel_velocity_mps = 0.0;
  std::uint16_t servo_frame_count = 0;  // the base's 100 Hz frame counter (wraps at 65536)
};

// Attitude and rates from the base's gyroscopes (the RMP balances on them).
struct ImuSample {
  Header header;
  double pitch_rad = 0.0;
  double roll_rad = 0.0;
  double pitch_rate_radps = 0.0;
  double roll_rate_radps = 0.0;
  double yaw_rate_radps = 0.0;
};

}  // namespace blockmap::msg
