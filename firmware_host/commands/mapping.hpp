// The mapping pipeline as `run` and `replay` drive it: the mapper sized from the robot's
// configuration, its memory reported against the budget before anything runs, and its plane
// updates and poses written out (outputs/map_outputs.hpp) as they come.
#pragma once

#include <chrono>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/hal/sim/robot.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "outputs/map_outputs.hpp"

namespace blockmap::cli {

struct MappingOptions {
  std::string out;
  std::string config;  // a TOML file whose [planes] table sets the detector
  std::string udp;     // HOST:PORT for the binary plane stream, or empty
  double budget_mib = 64.0;
  bool trajectory_only = false;  // localize only: trajectory.csv, no planes
};

// The mapper's configuration for `robot` (hal::sim::mapper_config_for) with the [planes]
// table of options.config when given. Throws ConfigError.
[[nodiscard]] pipeline::MapperConfig mapper_config_for(const hal::sim::RobotSpec& robot,
                                                       const MappingOptions& options);

class MappingSession {
 public:
  // Checks the configuration and the budget, takes the arena, initializes the mapper, prints
  // the memory report on `err`, and opens the outputs (with no options.out, the trajectory
  // only, to `out`). Empty when it worked, else why not.
  [[nodiscard]] std::string start(const pipeline::MapperConfig& config,
                                  const MappingOptions& options, std::ostream& out,
                                  std::ostream& err);
  [[nodiscard]] const MapOutputs& outputs() const noexcept { return outputs_; }

  [[nodiscard]] pipeline::Mapper& mapper() noexcept { return mapper_; }
  // Steps the pipeline over what it was given and writes what it produced.
  void pump();
  // No more input: the rest is processed, the planes finalized and the outputs closed. The
  // plane list's "seconds" is the wall time from start() to here. With the local frame's
  // place on Earth, the footprints are written in WGS-84 too.
  [[nodiscard]] std::string finish(const std::optional<hal::GeodeticPoint>& origin);
  // One line of counters for stderr; data_s: the span of the data mapped.
  void report(std::ostream& err, double data_s) const;

 private:
  std::unique_ptr<Arena> arena_;
  pipeline::Mapper mapper_;
  MapOutputs outputs_;
  std::vector<localize::Pose3> poses_;  // scratch for the localizer's poses
  std::chrono::steady_clock::time_point started_;
  double wall_s_ = 0.0;  // from start() to finish()
};

}  // namespace blockmap::cli
