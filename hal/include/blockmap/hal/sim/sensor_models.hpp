// How the simulated robot's sensors err, apart from when and how their bytes go out: the
// Segway's sensing of its true motion, and the GPS receiver's error. The simulated devices use
// them, and so does `blockmap import`, which makes a robot's device logs from a reference
// trajectory (a real vehicle's path with this robot's sensors).
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/hal/sim/motion.hpp"
#include "blockmap/hal/sim/random.hpp"
#include "blockmap/msg/gps_fix.hpp"

namespace blockmap::hal::sim {

// The Segway's sensing: wheel counts with the tyre-pressure scale error and random slip, a
// yaw-rate gyroscope with a bias and noise, and noisy pitch and roll. It keeps the base's
// integrators (the counts since start).
class BaseSensing {
 public:
  explicit BaseSensing(const config::BaseSpec& base) : base_(base) {}
  // What the base reports for the true state at the end of a cycle of dt_s.
  [[nodiscard]] protocol::segway_rmp::StatusCycle sense(const RobotState& state, double dt_s,
                                                        std::uint64_t cycle, SimRandom& random);

 private:
  config::BaseSpec base_;
  double left_m_ = 0.0;  // the base's integrators (reported, with its errors)
  double right_m_ = 0.0;
  double last_true_left_m_ = 0.0;
  double last_true_right_m_ = 0.0;
  double battery_v_ = 73.0;
};

// The receiver's error: a slow part (orbits, clocks, the atmosphere) and multipath, each a
// first-order Gauss-Markov process per axis with the spec's RMS and correlation time, started
// from its stationary distribution and advanced exactly for any interval.
class GpsErrorProcess {
 public:
  explicit GpsErrorProcess(const config::GpsSpec& spec);
  // Draws the starting error from the stationary distribution.
  void start(SimRandom& random);
  void advance(double dt_s, SimRandom& random);
  // East, north and up, metres, at the open-sky HDOP (a receiver scales it by its HDOP).
  [[nodiscard]] Eigen::Vector3d error_m() const noexcept;

 private:
  config::GpsSpec spec_;
  double slow_sigma_m_ = 0.0;  // per horizontal axis
  double multipath_sigma_m_ = 0.0;
  Eigen::Vector3d slow_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector2d multipath_m_ = Eigen::Vector2d::Zero();
};

// A receiver's time and date of a fix at `unix_s` (rounded to the millisecond).
void set_fix_utc(msg::GpsFix& fix, double unix_s) noexcept;

}  // namespace blockmap::hal::sim
