#include "blockmap/hal/sim/truth_cloud.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace blockmap::hal::sim {

TruthCloudSink::TruthCloudSink(PoseNoise noise, std::uint64_t seed)
    : noise_(noise), random_(seed, "truth_cloud.pose_noise") {}

void TruthCloudSink::draw_scan_error(TimestampNs stamp_ns) {
  Eigen::Matrix<double, 6, 1> fresh;
  for (Eigen::Index i = 0; i < 6; ++i) {
    fresh(i) = random_.gaussian() * (i < 3 ? noise_.angle_rad : noise_.shift_m);
  }
  if (noise_.correlation_s > 0.0 && drifting_) {
    // Gauss-Markov: decays towards zero by exp(-dt / tau) and is refreshed by just enough
    // new noise to keep the same standard deviation.
    // The two lasers' scans interleave: one may start a little before the other's last.
    const double dt_s = std::max(0.0, static_cast<double>(stamp_ns - error_stamp_ns_) * 1e-9);
    const double keep = std::exp(-dt_s / noise_.correlation_s);
    error_ = keep * error_ + std::sqrt(1.0 - keep * keep) * fresh;
  } else {
    error_ = fresh;
  }
  drifting_ = true;
  error_stamp_ns_ = std::max(error_stamp_ns_, stamp_ns);
  const Eigen::Vector3d angles = error_.head<3>();
  rotation_ = (Eigen::AngleAxisd(angles.z(), Eigen::Vector3d::UnitZ()) *
               Eigen::AngleAxisd(angles.y(), Eigen::Vector3d::UnitY()) *
               Eigen::AngleAxisd(angles.x(), Eigen::Vector3d::UnitX()))
                  .toRotationMatrix();
  shift_m_ = error_.tail<3>();
}

void TruthCloudSink::on_beam(std::size_t laser, const BeamTruth& beam) {
  if (!beam.returned) {
    return;
  }
  if (noise_.angle_rad > 0.0 || noise_.shift_m > 0.0) {
    if (laser != last_laser_ || beam.scan != last_scan_) {
      last_laser_ = laser;
      last_scan_ = beam.scan;
      draw_scan_error(beam.stamp_ns);
    }
    const Eigen::Vector3d ray = rotation_ * (beam.direction * beam.measured_range_m);
    points_.emplace_back((beam.origin_m + shift_m_ + ray).cast<float>());
    return;
  }
  points_.emplace_back((beam.origin_m + beam.direction * beam.measured_range_m).cast<float>());
}

TruthCloud simulate_truth_cloud(const World& world, const config::RobotSpec& robot,
                                const SimOptions& options, PoseNoise noise) {
  TruthCloudSink sink(noise, options.seed);
  Simulation simulation(world, robot, options);
  simulation.run(sink);
  return TruthCloud{std::move(sink.points()), simulation.scene().faces()};
}

}  // namespace blockmap::hal::sim
