// A simulated run's device messages, recorded once so that the mapper can be fed without the
// simulator (which allocates as it builds its scene and costs time of its own): odometry and
// IMU, GPS fixes in the world's frame, both lasers' scans and the true poses, in the order the
// devices published them. For the memory-budget tests and the mapper's benchmarks.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/pipeline/mapper.hpp"

namespace blockmap::testing {

class RecordedMapperInputs {
 public:
  RecordedMapperInputs(const std::string& world_name, double duration_s, std::uint64_t seed = 5) {
    const hal::config::RobotSpec robot = hal::config::load_robot("paper_rmp");
    const hal::sim::World world = hal::sim::load_world(world_name);
    hal::sim::SimOptions options;
    options.seed = seed;
    options.max_duration_s = duration_s;
    hal::FixConverter converter(world.site.origin);
    hal::sim::SimulatedRobot simulated(world, robot, options);
    started = simulated.start() == IoStatus::kOk;
    config = hal::config::mapper_config_for(robot);
    bool more = true;
    while (more) {
      more = simulated.advance();
      record(simulated, converter);
    }
    data_s = simulated.simulation().elapsed_s();
  }

  // Hands every message to `mapper` in the order the devices published them (true poses
  // only when its pose source is external), stepping it after each; then ends the input.
  template <typename OnStep>  // void(bool produced_update)
  void feed(pipeline::Mapper& mapper, OnStep&& on_step) const {
    const bool true_poses = mapper.config().pose_source == pipeline::PoseSource::kExternal;
    for (const Event& e : events) {
      switch (e.kind) {
        case Event::kBase:
          mapper.on_base(bases[e.index].first, bases[e.index].second);
          break;
        case Event::kFix:
          mapper.on_fix(fixes[e.index].first, fixes[e.index].second);
          break;
        case Event::kPose:
          if (!true_poses) {
            continue;
          }
          mapper.on_pose(poses[e.index]);
          break;
        case Event::kScan:
          static_cast<void>(mapper.on_scan(scans[e.index].first, *scans[e.index].second));
          break;
      }
      on_step(e.kind == Event::kScan);
    }
    mapper.end_of_input();
    on_step(false);
  }
  void feed(pipeline::Mapper& mapper) const {
    feed(mapper, [&mapper](bool) {
      while (mapper.step()) {
      }
    });
  }

  bool started = false;
  double data_s = 0.0;
  pipeline::MapperConfig config;
  struct Event {
    enum Kind : std::uint8_t { kBase, kFix, kPose, kScan } kind;
    std::size_t index;
  };
  std::vector<Event> events;
  std::vector<std::pair<msg::OdometrySample, msg::ImuSample>> bases;
  std::vector<std::pair<localize::GpsObservation, double>> fixes;
  std::vector<localize::Pose3> poses;
  std::vector<std::pair<std::size_t, std::unique_ptr<msg::LaserScan>>> scans;

 private:
  void record(hal::sim::SimulatedRobot& simulated, hal::FixConverter& converter) {
    msg::OdometrySample odometry;
    msg::ImuSample imu;
    while (simulated.odometry().try_pop(odometry) && simulated.imu().try_pop(imu)) {
      events.push_back({Event::kBase, bases.size()});
      bases.emplace_back(odometry, imu);
    }
    msg::GpsFix fix;
    while (simulated.fixes().try_pop(fix)) {
      localize::GpsObservation observation;
      double up_m = 0.0;
      if (converter.convert(fix, bases.empty() ? 0 : bases.back().first.header.stamp_ns,
                            observation, up_m)) {
        events.push_back({Event::kFix, fixes.size()});
        fixes.emplace_back(observation, up_m);
      }
    }
    hal::sim::SimulatedRobot::TrueState truth;
    while (simulated.truth().try_pop(truth)) {
      const hal::sim::RobotState& s = truth.state;
      events.push_back({Event::kPose, poses.size()});
      poses.push_back(localize::Pose3{truth.stamp_ns, s.position_m.x(), s.position_m.y(),
                                      s.position_m.z(), s.roll_rad, s.pitch_rad, s.yaw_rad});
    }
    for (std::size_t laser = 0; laser < simulated.laser_count(); ++laser) {
      auto scan = std::make_unique<msg::LaserScan>();
      while (simulated.scans(laser).try_pop(*scan)) {
        events.push_back({Event::kScan, scans.size()});
        scans.emplace_back(laser, std::move(scan));
        scan = std::make_unique<msg::LaserScan>();
      }
    }
  }
};

}  // namespace blockmap::testing
