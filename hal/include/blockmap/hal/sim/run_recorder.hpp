// Records a simulated run as a robot's logger would, into a folder (docs/log-formats.md):
//   rmp.candump               CAN traffic in can-utils' candump log format (interface can0)
//   laser_<name>.bytelog      each laser's serial bytes with receive times (docs/log-formats.md)
//   gps.nmea                  the GPS receiver's raw NMEA byte stream
//   truth.json                the true trajectory (100 Hz), every planar face with its returns,
//                             every building's footprint and shape
//   truth_gps.csv             every GPS epoch: true antenna position, the error, satellites
//   world.toml, robot.toml    the configurations the run used (given by the caller)
// Files are written as the run goes, through fixed stdio buffers: nothing grows with the run.
#pragma once

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "blockmap/hal/sim/simulation.hpp"

namespace blockmap::hal::sim {

class RunRecorder final : public SimSink {
 public:
  // Creates `folder` if needed and opens every file; throws std::runtime_error naming the file
  // that cannot be written.
  RunRecorder(std::filesystem::path folder, const Simulation& simulation);
  ~RunRecorder() override;
  RunRecorder(const RunRecorder&) = delete;
  RunRecorder& operator=(const RunRecorder&) = delete;

  void on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) override;
  void on_serial(std::size_t device, TimestampNs stamp_ns, protocol::byte_log::Direction direction,
                 std::span<const std::uint8_t> bytes) override;
  void on_truth_state(TimestampNs stamp_ns, const RobotState& state) override;
  void on_gps_epoch(const GpsTruth& truth) override;

  // Writes a configuration file as given.
  void write_text_file(std::string_view name, std::string_view text);
  // Completes truth.json (faces with their return counts, buildings) and closes every file;
  // throws std::runtime_error when a write failed (a full disk).
  void finish(std::uint64_t seed);

 private:
  struct File {
    std::FILE* handle = nullptr;
    std::unique_ptr<char[]> buffer;
    std::filesystem::path path;
  };
  File open(const std::string& name);
  void write(File& file, const void* data, std::size_t size);

  std::filesystem::path folder_;
  const Simulation& simulation_;
  File can_;
  std::vector<File> serial_;  // lasers (byte logs), then the GPS (raw NMEA)
  File truth_;
  File truth_gps_;
  bool first_state_ = true;
  bool failed_ = false;
};

}  // namespace blockmap::hal::sim
