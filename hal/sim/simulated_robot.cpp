#include "blockmap/hal/sim/simulated_robot.hpp"

#include <algorithm>

namespace blockmap::hal::sim {
namespace {

namespace lms = protocol::sick_lms2xx;

devices::SegwayBaseConfig base_config(const RobotSpec& robot) {
  devices::SegwayBaseConfig config;
  config.rmp.model = robot.base.model;
  config.rmp.yaw_sign = robot.base.yaw_sign;
  return config;
}

}  // namespace

// The device layer's view of a laser: its codec, and its timing when one mirror turn makes a
// scan (the interlaced 0.5 and 0.25 deg variants sweep over several turns, in an order the
// telegram does not give: their beams keep the scan's stamp).
devices::Lms2xxScannerConfig lms2xx_config_for(const LaserSpec& spec) {
  const lms::VariantGeometry geometry = lms::geometry(spec.variant);
  const bool single_turn = spec.variant == lms::AngularVariant::k180Deg1Deg ||
                           spec.variant == lms::AngularVariant::k100Deg1Deg;
  devices::Lms2xxScannerConfig config;
  if (single_turn) {
    config = devices::lms2xx_single_turn_timing(geometry.field_deg,
                                                geometry.resolution_centideg / 100.0);
  }
  config.codec.range_bits = spec.range_bits;
  config.codec.variant = spec.variant;
  return config;
}

pipeline::MapperConfig mapper_config_for(const RobotSpec& robot) {
  pipeline::MapperConfig config;
  config.localizer.antenna_m = robot.gps.antenna_m;
  config.laser_count = std::min(robot.lasers.size(), pipeline::kMaxLasers);
  // An LMS2xx scan has at most 401 beams (100 deg at 0.25 deg); a TiM's telegram says.
  constexpr std::size_t kLms2xxMaxBeams = 401;
  config.max_beams = kLms2xxMaxBeams;
  config.scans_per_s = 0.0;
  // The robot's wheels say where the ground is, so the ground far from the lasers can stay out
  // of the window (ScanProjectorConfig says why; docs/mapper.md, Speed, 2026-12-02): 8 m keeps
  // the dense ground near the robot, which makes the ground's plane, and halves benning's
  // window. `[projection] far_ground_range_m = 0` keeps every ground return.
  config.projection.axle_height_m = robot.base.wheel_radius_m;
  config.projection.far_ground_range_m = 8.0;
  for (std::size_t i = 0; i < config.laser_count; ++i) {
    const LaserSpec& laser = robot.lasers[i];
    const Mount& mount = laser.mount;
    config.laser_mounts[i] =
        map::SensorMount{mount.position_m, mount.roll_rad, mount.pitch_rad, mount.yaw_rad};
    if (laser.protocol != LaserProtocol::kLms2xx) {
      config.max_beams = msg::kMaxLaserBeams;
    }
    config.scans_per_s += laser.scan_rate_hz;  // at most one scan per mirror turn
  }
  return config;
}

SimulatedRobot::SimulatedRobot(const World& world, const RobotSpec& robot,
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
      base_(can_, odometry_, imu_, base_config(robot)),
      gps_(*serial_.back(), fixes_, devices::GpsReceiverConfig{}),
      fix_converter_(world.site.origin),
      last_base_ns_(simulation_.start_ns()) {
  // Serial devices are the lasers, in the robot's order, then the GPS.
  for (std::size_t i = 0; i < robot.lasers.size(); ++i) {
    scans_.push_back(std::make_unique<SpscQueue<msg::LaserScan, 8>>());
    lasers_.push_back(std::make_unique<devices::Lms2xxScanner>(*serial_[i], *scans_.back(),
                                                               lms2xx_config_for(robot.lasers[i])));
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
