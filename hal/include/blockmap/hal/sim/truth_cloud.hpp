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
  double angle_rad = 0.0;  // standard deviation per axis, per scan
  double shift_m = 0.0;    // standard deviation per axis, per scan
};

class TruthCloudSink : public SimSink {
 public:
  explicit TruthCloudSink(PoseNoise noise = {}, std::uint64_t seed = 11);

  void on_beam(std::size_t laser, const BeamTruth& beam) override;

  [[nodiscard]] const std::vector<Eigen::Vector3f>& points() const noexcept { return points_; }
  [[nodiscard]] std::vector<Eigen::Vector3f>& points() noexcept { return points_; }

 private:
  void draw_scan_error();

  PoseNoise noise_;
  SimRandom random_;
  std::vector<Eigen::Vector3f> points_;
  std::size_t last_laser_ = static_cast<std::size_t>(-1);
  std::uint32_t last_scan_ = 0;
  Eigen::Matrix3d rotation_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d shift_m_ = Eigen::Vector3d::Zero();
};

struct TruthCloud {
  std::vector<Eigen::Vector3f> points_m;  // local frame
  std::vector<TruthFace> faces;           // with the returns each got
};

// Runs the simulation of `world` with `robot` and returns its truth cloud and faces.
[[nodiscard]] TruthCloud simulate_truth_cloud(const World& world, const RobotSpec& robot,
                                              const SimOptions& options, PoseNoise noise = {});

}  // namespace blockmap::hal::sim
