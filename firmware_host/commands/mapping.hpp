// The mapping pipeline as `run` and `replay` drive it: the mapper sized from the robot's
// configuration, its memory reported against the budget before anything runs, and its plane
// updates and poses written out (outputs/map_outputs.hpp) as they come.
#pragma once

#include <chrono>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "commands/memory_budget.hpp"
#include "outputs/map_outputs.hpp"
#include "outputs/output_thread.hpp"

namespace CLI {
class App;
}

namespace blockmap::cli {

struct MappingOptions {
  std::string out;
  std::string config;  // a TOML file: [planes], [buildings], [window], [projection]
  std::string udp;     // HOST:PORT for the binary plane stream, or empty
  double budget_mib = kDefaultMapperBudgetMiB;
  bool trajectory_only = false;  // localize only: trajectory.csv, no planes
  bool cloud = false;            // also cloud.ply: every projected point (kept in memory)
  bool resume = false;           // carry on the streams in `out` (a resumed map): append to them
};

// Every projected point, for cloud.ply. A tool for looking at a run afterwards, not part of
// the onboard pipeline: it grows with the run.
class CloudRecorder final : public pipeline::PointSink {
 public:
  void on_points(std::span<const Eigen::Vector3f> points_m) override {
    points_.insert(points_.end(), points_m.begin(), points_m.end());
  }
  [[nodiscard]] const std::vector<Eigen::Vector3f>& points() const noexcept { return points_; }

 private:
  std::vector<Eigen::Vector3f> points_;
};

// --udp HOST:PORT into `destination`, its form and port checked as the command line is read.
void add_udp_option(CLI::App& command, std::string& destination);

// `config` with the tables of options.config (config/README.md) when given. Throws
// ConfigError.
[[nodiscard]] pipeline::MapperConfig with_config_file(const pipeline::MapperConfig& config,
                                                      const MappingOptions& options);
// The mapper's configuration for `robot` (hal::config::mapper_config_for) with the tables of
// options.config when given. Throws ConfigError.
[[nodiscard]] pipeline::MapperConfig mapper_config_for(const hal::config::RobotSpec& robot,
                                                       const MappingOptions& options);

class MappingSession {
 public:
  // Checks the configuration and the budget, takes the arena, initializes the mapper and
  // prints the memory report on `err`. Empty when it worked, else what in the configuration
  // is wrong.
  [[nodiscard]] std::string start(const pipeline::MapperConfig& config,
                                  const MappingOptions& options, std::ostream& err);
  // Opens the outputs (with no options.out, the trajectory only, to `out`). Empty when it
  // worked, else which file or folder cannot be written.
  [[nodiscard]] std::string open_outputs(const MappingOptions& options, std::ostream& out);
  [[nodiscard]] const MapOutputs& outputs() const noexcept { return outputs_; }
  [[nodiscard]] MapOutputs& outputs() noexcept { return outputs_; }

  [[nodiscard]] pipeline::Mapper& mapper() noexcept { return mapper_; }
  // Steps the pipeline over what it was given and writes what it produced: itself, or through
  // `thread` once given one (the daemon: nothing is formatted or written on the pipeline
  // thread). nullptr: itself again (the thread finished).
  void pump();
  void write_through(OutputThread* thread) noexcept { output_thread_ = thread; }
  // No more input: the rest is processed, the planes finalized and the outputs closed. The
  // plane list's "seconds" is the wall time from start() to here. With the local frame's
  // place on Earth, the footprints are written in WGS-84 too; with options.cloud, cloud.ply.
  [[nodiscard]] std::string finish(const std::optional<hal::GeodeticPoint>& origin);
  // One line of counters for stderr; data_s: the span of the data mapped.
  void report(std::ostream& err, double data_s) const;

 private:
  std::unique_ptr<Arena> arena_;
  pipeline::Mapper mapper_;
  MapOutputs outputs_;
  OutputThread* output_thread_ = nullptr;
  std::vector<localize::Pose3> poses_;  // scratch for the localizer's poses
  std::optional<CloudRecorder> cloud_;  // options.cloud
  std::chrono::steady_clock::time_point started_;
  double wall_s_ = 0.0;  // from start() to finish()
};

}  // namespace blockmap::cli
