// The point cloud of a simulated run built from the true trajectory: every returned beam
// becomes the point at its measured range along its true ray, in the local frame. Optional
// pose noise perturbs each scan as a whole (rotation about the laser, then a shift), the way
// an error in the pose estimate would. For tests, benchmarks and the planes command.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "blockmap/hal/sim/random.hpp"
#include "blockmap/hal/sim/simulation.hpp"

namespace blockmap::hal::sim {

struct PoseNoise {
  double angle_rad = 0.0;  // standard deviation per axis
  double shift_m = 0.0;    // standard deviation per axis
  // 0: every scan of every laser gets its own independent error. > 0: the robot's pose error
  // drifts as a first-order Gauss-Markov process with this time constant, shared by both
  // lasers; a localisation filter's error changes with odometry and GPS, not from one scan to
  // the next 13 ms later.
  double correlation_s = 0.0;
};

class TruthCloudSink : public SimSink {
 public:
  explicit TruthCloudSink(PoseNoise noise = {}, std::uint64_t seed = 11);

  void on_beam(std::size_t laser, const BeamTruth& beam) override;

  [[nodiscard]] const std::vector<Eigen::Vector3f>& points() const noexcept { return points_; }
  [[nodiscard]] std::vector<Eigen::Vector3f>& points() noexcept { return points_; }

 private:
  void draw_scan_error(TimestampNs stamp_ns);

  PoseNoise noise_;
  SimRandom random_;
  std::vector<Eigen::Vector3f> points_;
  std::size_t last_laser_ = static_cast<std::size_t>(-1);
  std::uint32_t last_scan_ = 0;
  Eigen::Matrix<double, 6, 1> error_ = Eigen::Matrix<double, 6, 1>::Zero();  // angles, shift
  bool drifting_ = false;  // error_ holds a drawn state (correlated noise)
  TimestampNs error_stamp_ns_ = 0;
  Eigen::Matrix3d rotation_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d shift_m_ = Eigen::Vector3d::Zero();
};

struct TruthCloud {
  std::vector<Eigen::Vector3f> points_m;  // local frame
  std::vector<TruthFace> faces;           // with the returns each got
};

// Runs the simulation of `world` with `robot` and returns its truth cloud and faces.
[[nodiscard]] TruthCloud simulate_truth_cloud(const World& world, const config::RobotSpec& robot,
                                              const SimOptions& options, PoseNoise noise = {});

}  // namespace blockmap::hal::sim
