#include "blockmap/hal/sim/simulated_robot.hpp"

#include <algorithm>

namespace blockmap::hal::sim {
SimulatedRobot::SimulatedRobot(const World& world, const config::RobotSpec& robot,
                               const SimOptions& options)
    : simulation_(world, robot, options),
      can_(clock_, {}, pending_, sent_),
      serial_([&] {
        std::vector<std::unique_ptr<SimSerialPort>> ports;
        for (std::size_t i = 0; i < simulation_.serial_device_count(); ++i) {
          ports.push_back(std::make_unique<SimSerialPort>());
        }
        return ports;
      }()),
      serial_ptrs_([&] {
        std::vector<SimSerialPort*> ptrs;
        for (const auto& port : serial_) {
          ptrs.push_back(port.get());
        }
        return ptrs;
      }()),
      ports_(clock_, can_, serial_ptrs_),
      base_(can_, odometry_, imu_, config::segway_base_config_for(robot)),
      gps_(*serial_.back(), fixes_, devices::GpsReceiverConfig{}),
      fix_converter_(world.site.origin),
      last_base_ns_(simulation_.start_ns()) {
  // Serial devices are the lasers, in the robot's order, then the GPS.
  for (std::size_t i = 0; i < robot.lasers.size(); ++i) {
    scans_.push_back(std::make_unique<SpscQueue<msg::LaserScan, 8>>());
    lasers_.push_back(std::make_unique<devices::Lms2xxScanner>(
        *serial_[i], *scans_.back(), config::lms2xx_config_for(robot.lasers[i])));
  }
  clock_.set_ns(simulation_.start_ns());
  static_cast<void>(base_.install_filters());
}

SimulatedRobot::~SimulatedRobot() = default;

IoStatus SimulatedRobot::start() {
  for (const auto& laser : lasers_) {
    if (const IoStatus status = laser->start(); status != IoStatus::kOk) {
      return status;
    }
  }
  return IoStatus::kOk;
}

bool SimulatedRobot::advance() {
  const bool more = simulation_.step(*this);
  static_cast<void>(base_.poll(0));
  for (const auto& laser : lasers_) {
    static_cast<void>(laser->poll(0));
  }
  static_cast<void>(gps_.poll(0));
  return more;
}

void SimulatedRobot::feed(pipeline::Mapper& mapper, bool true_poses) {
  msg::OdometrySample odometry;
  msg::ImuSample imu;
  while (odometry_.try_pop(odometry) && imu_.try_pop(imu)) {
    last_base_ns_ = odometry.header.stamp_ns;
    mapper.on_base(odometry, imu);
  }
  msg::GpsFix fix;
  while (fixes_.try_pop(fix)) {
    localize::GpsObservation observation;
    double up_m = 0.0;
    if (fix_converter_.convert(fix, last_base_ns_, observation, up_m)) {
      mapper.on_fix(observation, up_m);
    }
  }
  TrueState truth;
  while (truth_.try_pop(truth)) {
    if (true_poses) {
      const RobotState& s = truth.state;
      mapper.on_pose(localize::Pose3{truth.stamp_ns, s.position_m.x(), s.position_m.y(),
                                     s.position_m.z(), s.roll_rad, s.pitch_rad, s.yaw_rad});
    }
  }
  for (std::size_t laser = 0; laser < scans_.size(); ++laser) {
    while (scans_[laser]->try_pop(scan_)) {
      static_cast<void>(mapper.on_scan(laser, scan_));
    }
  }
}

void SimulatedRobot::on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) {
  ports_.on_can_frame(stamp_ns, frame);
}

void SimulatedRobot::on_serial(std::size_t device, TimestampNs stamp_ns,
                               protocol::byte_log::Direction direction,
                               std::span<const std::uint8_t> bytes) {
  ports_.on_serial(device, stamp_ns, direction, bytes);
}

void SimulatedRobot::on_truth_state(TimestampNs stamp_ns, const RobotState& state) {
  if (!truth_.try_push(TrueState{stamp_ns, state})) {
    ++truth_dropped_;
  }
}

}  // namespace blockmap::hal::sim
