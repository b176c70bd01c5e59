#include "blockmap/hal/sim/truth_cloud.hpp"

#include <Eigen/Geometry>

namespace blockmap::hal::sim {

TruthCloudSink::TruthCloudSink(PoseNoise noise, std::uint64_t seed)
    : noise_(noise), random_(seed, "truth_cloud.pose_noise") {}

void TruthCloudSink::draw_scan_error() {
  const Eigen::Vector3d angles(random_.gaussian() * noise_.angle_rad,
                               random_.gaussian() * noise_.angle_rad,
                               random_.gaussian() * noise_.angle_rad);
  rotation_ = (Eigen::AngleAxisd(angles.z(), Eigen::Vector3d::UnitZ()) *
               Eigen::AngleAxisd(angles.y(), Eigen::Vector3d::UnitY()) *
               Eigen::AngleAxisd(angles.x(), Eigen::Vector3d::UnitX()))
                  .toRotationMatrix();
  shift_m_ =
      Eigen::Vector3d(random_.gaussian(), random_.gaussian(), random_.gaussian()) * noise_.shift_m;
}

void TruthCloudSink::on_beam(std::size_t laser, const BeamTruth& beam) {
  if (!beam.returned) {
    return;
  }
  if (noise_.angle_rad > 0.0 || noise_.shift_m > 0.0) {
    if (laser != last_laser_ || beam.scan != last_scan_) {
      last_laser_ = laser;
      last_scan_ = beam.scan;
      draw_scan_error();
    }
    const Eigen::Vector3d ray = rotation_ * (beam.direction * beam.measured_range_m);
    points_.emplace_back((beam.origin_m + shift_m_ + ray).cast<float>());
    return;
  }
  points_.emplace_back((beam.origin_m + beam.direction * beam.measured_range_m).cast<float>());
}

TruthCloud simulate_truth_cloud(const World& world, const RobotSpec& robot,
                                const SimOptions& options, PoseNoise noise) {
  TruthCloudSink sink(noise, options.seed);
  Simulation simulation(world, robot, options);
  simulation.run(sink);
  return TruthCloud{std::move(sink.points()), simulation.scene().faces()};
}

}  // namespace blockmap::hal::sim
