// The simulated robot as the pipeline sees a real one: a Simulation's CAN frames and serial
// bytes go onto loopback ports (SimPorts), and the same devices as on the robot (SegwayBase,
// one Lms2xxScanner per laser, GpsReceiver) read, decode and publish them into queues. This is
// what `blockmap run` maps when it has no robot: the decoders see the devices' real bytes.
// The robot's true state is kept too, for runs that map with true poses and for evaluation.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/gps_observations.hpp"
#include "blockmap/hal/sim/loopback_can_bus.hpp"
#include "blockmap/hal/sim/sim_ports.hpp"
#include "blockmap/hal/sim/simulation.hpp"
#include "blockmap/pipeline/mapper.hpp"

namespace blockmap::hal::sim {

class SimulatedRobot final : public SimSink {
 public:
  struct TrueState {
    TimestampNs stamp_ns = 0;
    RobotState state;
  };

  SimulatedRobot(const World& world, const config::RobotSpec& robot, const SimOptions& options);
  ~SimulatedRobot() override;
  SimulatedRobot(const SimulatedRobot&) = delete;
  SimulatedRobot& operator=(const SimulatedRobot&) = delete;

  // Asks every laser for continuous output (as on the robot).
  IoStatus start();
  // Runs the simulation's next event and lets every device read its port; false when the run
  // is over (the queues may still hold messages).
  bool advance();

  SpscQueueRef<msg::OdometrySample>& odometry() noexcept { return odometry_; }
  SpscQueueRef<msg::ImuSample>& imu() noexcept { return imu_; }
  SpscQueueRef<msg::GpsFix>& fixes() noexcept { return fixes_; }
  SpscQueueRef<msg::LaserScan>& scans(std::size_t laser) noexcept { return *scans_[laser]; }
  SpscQueueRef<TrueState>& truth() noexcept { return truth_; }
  // Hands everything the devices published since the last call to `mapper`: base groups,
  // GPS fixes (in the world's local frame) and scans, and with true_poses the true states as
  // poses (drained either way).
  void feed(pipeline::Mapper& mapper, bool true_poses);
  [[nodiscard]] std::size_t laser_count() const noexcept { return lasers_.size(); }

  [[nodiscard]] const Simulation& simulation() const noexcept { return simulation_; }
  [[nodiscard]] const devices::SegwayBase& base() const noexcept { return base_; }
  [[nodiscard]] const devices::Lms2xxScanner& laser(std::size_t i) const noexcept {
    return *lasers_[i];
  }
  [[nodiscard]] const devices::GpsReceiver& gps() const noexcept { return gps_; }
  // States the truth queue had no room for (the caller did not drain it).
  [[nodiscard]] std::uint64_t truth_dropped() const noexcept { return truth_dropped_; }

  void on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) override;
  void on_serial(std::size_t device, TimestampNs stamp_ns, protocol::byte_log::Direction direction,
                 std::span<const std::uint8_t> bytes) override;
  void on_truth_state(TimestampNs stamp_ns, const RobotState& state) override;

 private:
  Simulation simulation_;
  ManualClock clock_;
  std::array<PendingCanFrame, 256> pending_{};
  std::array<CanFrame, 16> sent_{};
  LoopbackCanBus can_;
  std::vector<std::unique_ptr<SimSerialPort>> serial_;
  std::vector<SimSerialPort*> serial_ptrs_;
  SimPorts ports_;
  SpscQueue<msg::OdometrySample, 256> odometry_;
  SpscQueue<msg::ImuSample, 256> imu_;
  SpscQueue<msg::GpsFix, 64> fixes_;
  SpscQueue<TrueState, 256> truth_;
  std::vector<std::unique_ptr<SpscQueue<msg::LaserScan, 8>>> scans_;
  devices::SegwayBase base_;
  std::vector<std::unique_ptr<devices::Lms2xxScanner>> lasers_;
  devices::GpsReceiver gps_;
  std::uint64_t truth_dropped_ = 0;
  FixConverter fix_converter_;
  TimestampNs last_base_ns_ = 0;
  msg::LaserScan scan_;  // feed()'s buffer
};

}  // namespace blockmap::hal::sim
