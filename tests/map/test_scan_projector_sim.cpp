// Scan projection against the simulator: every beam of a few scans of both lasers of the
// paper's robot, projected with the true pose at its time, lands where the simulator's ray
// met the world. This holds the conventions together: the mount's angle order, the sign of
// the Segway's pitch (the run starts by accelerating, so the robot pitches), the axle origin.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "blockmap/hal/sim/simulation.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/map/scan_projector.hpp"

namespace blockmap::map {
namespace {

struct StampedState {
  TimestampNs stamp_ns = 0;
  hal::sim::RobotState state;
};

class Recorder : public hal::sim::SimSink {
 public:
  Recorder(std::uint32_t first_scan, std::uint32_t end_scan)
      : first_scan_(first_scan), end_scan_(end_scan) {}
  void on_truth_state(TimestampNs stamp_ns, const hal::sim::RobotState& state) override {
    states.push_back({stamp_ns, state});
  }
  void on_beam(std::size_t laser, const hal::sim::BeamTruth& beam) override {
    if (beam.returned && beam.scan >= first_scan_ && beam.scan < end_scan_) {
      beams[laser].push_back(beam);
    }
  }
  std::vector<StampedState> states;
  std::array<std::vector<hal::sim::BeamTruth>, 2> beams;

 private:
  std::uint32_t first_scan_;
  std::uint32_t end_scan_;
};

// The true pose at a time, linear between the 100 Hz states around it.
localize::Pose3 true_pose_at(const std::vector<StampedState>& states, TimestampNs stamp_ns) {
  std::size_t i = 1;
  while (i + 1 < states.size() && states[i].stamp_ns < stamp_ns) {
    ++i;
  }
  const StampedState& a = states[i - 1];
  const StampedState& b = states[i];
  const double f =
      static_cast<double>(stamp_ns - a.stamp_ns) / static_cast<double>(b.stamp_ns - a.stamp_ns);
  const auto mix = [f](double x, double y) { return x + f * (y - x); };
  const Eigen::Vector3d p = a.state.position_m + f * (b.state.position_m - a.state.position_m);
  const double yaw_step = std::remainder(b.state.yaw_rad - a.state.yaw_rad, 2.0 * std::numbers::pi);
  return {stamp_ns,
          p.x(),
          p.y(),
          p.z(),
          mix(a.state.roll_rad, b.state.roll_rad),
          mix(a.state.pitch_rad, b.state.pitch_rad),
          a.state.yaw_rad + f * yaw_step};
}

TEST(ScanProjectorSim, EveryBeamLandsWhereTheSimulatorsRayMetTheWorld) {
  const hal::config::RobotSpec robot = hal::config::load_robot("paper_rmp");
  ASSERT_EQ(robot.lasers.size(), 2u);
  hal::sim::SimOptions options;
  options.seed = 5;
  options.max_duration_s = 4.0;
  // Scans 150-160 (two seconds in): the robot is accelerating, so it pitches.
  Recorder recorder(150, 160);
  hal::sim::Simulation simulation(hal::sim::load_world("usc_block"), robot, options);
  simulation.run(recorder);
  ASSERT_GE(recorder.states.size(), 2u);
  double largest_pitch_rad = 0.0;
  for (const StampedState& s : recorder.states) {
    largest_pitch_rad = std::max(largest_pitch_rad, std::abs(s.state.pitch_rad));
  }
  EXPECT_GT(largest_pitch_rad, 0.01);  // the test would not see a pitch sign error otherwise
  for (std::size_t laser = 0; laser < 2; ++laser) {
    const hal::config::LaserSpec& spec = robot.lasers[laser];
    const auto geometry = hal::protocol::sick_lms2xx::geometry(spec.variant);
    const double start_rad = -static_cast<double>(geometry.field_deg) * std::numbers::pi / 360.0;
    const double step_rad =
        static_cast<double>(geometry.resolution_centideg) * std::numbers::pi / 18000.0;
    ScanProjectorConfig config;
    config.min_range_m = 0.0;
    config.max_range_m = 1000.0;
    ScanProjector projector(SensorMount{spec.mount.position_m, spec.mount.roll_rad,
                                        spec.mount.pitch_rad, spec.mount.yaw_rad},
                            config);
    ASSERT_GT(recorder.beams[laser].size(), 500u) << spec.name;
    double worst_m = 0.0;
    for (const hal::sim::BeamTruth& beam : recorder.beams[laser]) {
      msg::LaserScan scan;
      scan.header.stamp_ns = beam.stamp_ns;
      scan.beam_count = 1;
      scan.start_angle_rad = start_rad + static_cast<double>(beam.beam) * step_rad;
      scan.ranges_m[0] = static_cast<float>(beam.measured_range_m);
      scan.status[0] = msg::BeamStatus::kValid;
      const localize::Pose3 pose = true_pose_at(recorder.states, beam.stamp_ns);
      std::array<Eigen::Vector3f, 1> out{};
      ASSERT_EQ(projector.project(scan, pose, pose, out), 1u);
      const Eigen::Vector3d expected = beam.origin_m + beam.measured_range_m * beam.direction;
      worst_m = std::max(worst_m, (out[0].cast<double>() - expected).norm());
    }
    // The simulator moves each scan's laser linearly over the scan; the test interpolates
    // the 100 Hz states: both are straight lines over 10-13 ms of a smooth motion.
    std::printf("%s laser: %zu beams, worst %.2f mm\n", spec.name.c_str(),
                recorder.beams[laser].size(), worst_m * 1000.0);
    EXPECT_LT(worst_m, 0.005) << spec.name;
  }
}

}  // namespace
}  // namespace blockmap::map
