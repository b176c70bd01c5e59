// A run of the simulated robot through a simulated world: the Segway drives the world's path,
// and its devices produce the bytes the real ones would, at the times they would: the RMP's
// status frames on the CAN bus every 10 ms, each LMS2xx's telegrams on its serial line, the GPS
// receiver's NMEA sentences on its own. Everything is handed, in time order, to a SimSink: log
// writers (`blockmap simulate`), the simulated ports the robot's devices read (SimPorts), or a
// test. Ground truth comes out beside the bytes: the robot's true state, every beam's true
// range and face, every GPS epoch's true antenna position.
//
// The simulator streams: all memory is taken in the constructor and a run of any length uses
// the same (tests/memory proves that step() never allocates).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/can_frame.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/protocol/byte_log.hpp"
#include "blockmap/hal/sim/motion.hpp"
#include "blockmap/hal/sim/scene.hpp"
#include "blockmap/hal/sim/world.hpp"

namespace blockmap::hal::sim {

// One beam of a simulated scan, as it really was.
struct BeamTruth {
  TimestampNs stamp_ns = 0;  // when the beam was measured
  std::uint32_t scan = 0;    // the laser's scan number
  std::uint16_t beam = 0;
  Vec3 origin_m = Vec3::Zero();
  Vec3 direction = Vec3::UnitX();  // unit, world frame
  Hit hit;                         // what it hit, at the true range
  bool returned = false;           // a valid range was sent (not lost, not beyond range)
  double measured_range_m = 0.0;   // the range before encoding (with noise)
};

// One GPS epoch, as it really was.
struct GpsTruth {
  TimestampNs epoch_ns = 0;
  Vec3 antenna_m = Vec3::Zero();  // true antenna position, local frame
  Vec3 error_m = Vec3::Zero();    // what the receiver added
  int satellites_visible = 0;
  double hdop = 0.0;
  bool fix = false;  // enough satellites for a position
};

// Serial devices are numbered lasers first (in robot order), then the GPS receiver.
class SimSink {
 public:
  SimSink() = default;
  SimSink(const SimSink&) = delete;
  SimSink& operator=(const SimSink&) = delete;
  virtual ~SimSink() = default;

  virtual void on_can_frame(TimestampNs /*stamp_ns*/, const CanFrame& /*frame*/) {}
  virtual void on_serial(std::size_t /*device*/, TimestampNs /*stamp_ns*/,
                         protocol::byte_log::Direction /*direction*/,
                         std::span<const std::uint8_t> /*bytes*/) {}
  // The robot's true state at every RMP cycle (100 Hz).
  virtual void on_truth_state(TimestampNs /*stamp_ns*/, const RobotState& /*state*/) {}
  virtual void on_beam(std::size_t /*laser*/, const BeamTruth& /*beam*/) {}
  virtual void on_gps_epoch(const GpsTruth& /*truth*/) {}
};

struct SimOptions {
  std::uint64_t seed = 1;
  // Stop after this much simulated time even if the path is not done; 0: run the whole path.
  double max_duration_s = 0.0;
  // After the robot stops, the devices go on for this long (the paper's runs end standing).
  double hold_after_stop_s = 1.0;
  // The GPS receiver sends nothing from gps_silent_from_s to gps_silent_to_s of the run (a
  // cable pulled, a receiver resetting): a fault test. Its error process runs on, so that the
  // fixes after the silence are those of the same run without it.
  double gps_silent_from_s = 0.0;
  double gps_silent_to_s = 0.0;
  // This share of the fixes is off by gps_jump_m in a random direction (multipath: a
  // reflection taken for the direct signal); the rest of the run is as without them.
  double gps_jump_fraction = 0.0;
  double gps_jump_m = 0.0;
};

struct SimStats {
  std::uint64_t rmp_cycles = 0;
  std::uint64_t gps_epochs = 0;
  std::uint64_t gps_epochs_without_fix = 0;
  std::uint64_t gps_epochs_silent = 0;       // SimOptions::gps_silent_*: computed, not sent
  std::vector<std::uint64_t> scans_sent;     // per laser
  std::vector<std::uint64_t> scans_skipped;  // per laser: the serial line was still busy
  std::vector<std::uint64_t> beams_returned;
};

class Simulation {
 public:
  Simulation(const World& world, const config::RobotSpec& robot, const SimOptions& options);
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  // Runs the next event (one device's output, or the RMP's cycle); false when the run is over.
  bool step(SimSink& sink);
  // step() until the run is over.
  void run(SimSink& sink);

  // Unix time of the run's first instant, in ns: every stamp is on this time base.
  [[nodiscard]] TimestampNs start_ns() const noexcept;
  [[nodiscard]] TimestampNs now_ns() const noexcept;
  [[nodiscard]] double elapsed_s() const noexcept;
  [[nodiscard]] bool finished() const noexcept;

  [[nodiscard]] const Scene& scene() const noexcept;
  [[nodiscard]] const RobotMotion& motion() const noexcept;
  [[nodiscard]] const config::RobotSpec& robot() const noexcept;
  [[nodiscard]] const World& world() const noexcept;
  [[nodiscard]] const SimStats& stats() const noexcept;
  // Serial device names: "laser_<name>" for lasers, "gps".
  [[nodiscard]] std::string serial_device_name(std::size_t device) const;
  [[nodiscard]] std::size_t serial_device_count() const noexcept;
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace blockmap::hal::sim
