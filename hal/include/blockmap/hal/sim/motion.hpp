// How the simulated Segway moves: it follows the world's path by pure pursuit, slows for turns
// and for the end, accelerates within its limits, pitches with its acceleration and with the
// bumps under its wheels, and rolls with the ground across its axle. Integrated at 200 Hz;
// the most recent states are kept in a ring so that sensors can ask for the pose at any instant
// of the last second (a laser beam's, a GPS epoch's).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <vector>

#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/terrain.hpp"
#include "blockmap/hal/sim/world.hpp"

namespace blockmap::hal::sim {

// The true state of the robot frame (robot.hpp) at time t_s after the start of the run.
struct RobotState {
  double t_s = 0.0;
  Vec3 position_m = Vec3::Zero();  // the axle's middle
  double roll_rad = 0.0;
  double pitch_rad = 0.0;  // positive: nose down
  double yaw_rad = 0.0;    // counter-clockwise from east
  double speed_mps = 0.0;
  double accel_mps2 = 0.0;
  double yaw_rate_radps = 0.0;
  double pitch_rate_radps = 0.0;
  double roll_rate_radps = 0.0;
  double left_wheel_m = 0.0;  // true travel of each wheel since the start
  double right_wheel_m = 0.0;

  [[nodiscard]] Eigen::Matrix3d rotation() const;
};

class RobotMotion {
 public:
  static constexpr double kStepS = 0.005;
  static constexpr std::size_t kHistory = 256;  // 1.28 s of states

  RobotMotion(const config::BaseSpec& base, const Path& path, const Terrain& terrain);

  // Integrates until the latest state is at or after t_s.
  void advance_to(double t_s) noexcept;
  // The state at t_s, interpolated; t_s must lie within the kept history (CHECK).
  [[nodiscard]] RobotState state_at(double t_s) const;
  [[nodiscard]] const RobotState& latest() const noexcept { return history_[latest_index_]; }
  // The path is done and the robot has stopped.
  [[nodiscard]] bool finished() const noexcept { return finished_; }
  [[nodiscard]] double path_length_m() const noexcept { return cumulative_m_.back(); }
  [[nodiscard]] double distance_m() const noexcept { return distance_m_; }

 private:
  void step() noexcept;
  // Projection of p on the path near the current progress, as an arc length.
  [[nodiscard]] double project(const Vec2& p) const noexcept;
  [[nodiscard]] Vec2 point_at(double s_m) const noexcept;
  void settle_on_ground(RobotState& state) const noexcept;

  config::BaseSpec base_;
  const Terrain& terrain_;
  std::vector<Vec2> waypoints_;
  std::vector<double> cumulative_m_;
  std::array<RobotState, kHistory> history_{};
  std::size_t latest_index_ = 0;
  std::size_t count_ = 0;
  double progress_m_ = 0.0;
  std::size_t segment_ = 0;
  double distance_m_ = 0.0;
  double cruise_speed_mps_ = 1.0;
  bool finished_ = false;
};

}  // namespace blockmap::hal::sim
