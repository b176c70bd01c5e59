// `blockmap run [--config FILE] [--out DIR]`: the onboard mapper. With a [devices] table in the
// config, the on-robot daemon maps from the robot's devices (daemon/daemon.hpp, config/README.md).
// With no robot attached, it maps the built-in simulated city block: the
// simulated Segway, lasers and GPS put their real bytes on loopback ports, the same device
// layer as on the robot decodes them, and the pipeline (particle filter, scan projection,
// sliding voxel window, Hough planes, plane registry) maps as it goes, writing the plane
// stream, the trajectory and, at the end, the plane list and a VRML map
// (docs/formats.md, run outputs).
#include <CLI/CLI.hpp>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/daemon_config.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"
#include "commands/mapping.hpp"
#include "daemon/daemon.hpp"

namespace blockmap::cli {
namespace {

struct RunOptions {
  MappingOptions mapping;
  std::string world = "usc_block";
  std::string robot = "paper_rmp";
  std::uint64_t seed = 1;
  double duration_s = 0.0;
  std::string poses = "filter";
  int laps = 1;
  std::vector<double> gps_silent_s;  // FROM TO: the simulated receiver sends nothing between
};

// The simulation's options of a run.
hal::sim::SimOptions sim_options_of(const RunOptions& options) {
  hal::sim::SimOptions sim;
  sim.seed = options.seed;
  sim.max_duration_s = options.duration_s;
  if (options.gps_silent_s.size() == 2) {
    sim.gps_silent_from_s = options.gps_silent_s[0];
    sim.gps_silent_to_s = options.gps_silent_s[1];
  }
  return sim;
}

// With a [devices] table in --config: the on-robot daemon (daemon/daemon.hpp).
int run_on_devices(const RunOptions& options, std::ostream& err) {
  daemon::DaemonOptions daemon_options;
  daemon_options.config = hal::config::load_daemon_config(options.mapping.config);
  daemon_options.config_source = options.mapping.config;
  daemon_options.mapping = options.mapping;
  daemon_options.sim = sim_options_of(options);
  daemon_options.laps = options.laps;
  return daemon::run_daemon(std::move(daemon_options), err);
}

int run(const RunOptions& options, std::ostream& err) {
  if (!options.mapping.config.empty() && hal::config::file_has_devices(options.mapping.config)) {
    return run_on_devices(options, err);
  }
  hal::sim::World world = hal::sim::load_world(options.world);
  if (const std::string problem = hal::sim::repeat_laps(world, options.laps); !problem.empty()) {
    err << "blockmap: run: " << problem << '\n';
    return kExitUsage;
  }
  const hal::config::RobotSpec robot = hal::config::load_robot(options.robot);
  if (options.poses != "filter" && options.poses != "truth") {
    err << "blockmap: run: --poses is filter or truth\n";
    return kExitUsage;
  }
  pipeline::MapperConfig config = mapper_config_for(robot, options.mapping);
  const bool true_poses = options.poses == "truth";
  config.pose_source =
      true_poses ? pipeline::PoseSource::kExternal : pipeline::PoseSource::kLocalizer;
  const hal::sim::SimOptions sim_options = sim_options_of(options);
  auto simulated = std::make_unique<hal::sim::SimulatedRobot>(world, robot, sim_options);
  if (simulated->start() != IoStatus::kOk) {
    err << "blockmap: run: the simulated lasers did not start\n";
    return kExitFailure;
  }
  auto session = std::make_unique<MappingSession>();
  if (const std::string problem = session->start(config, options.mapping, err); !problem.empty()) {
    err << "blockmap: run: " << problem << '\n';
    return kExitUsage;
  }
  if (const std::string problem = session->open_outputs(options.mapping, err); !problem.empty()) {
    err << "blockmap: run: " << problem << '\n';
    return kExitFailure;
  }
  bool more = true;
  while (more) {
    more = simulated->advance();
    simulated->feed(session->mapper(), true_poses);
    session->pump();
  }
  if (const std::string problem = session->finish(simulated->simulation().world().site.origin);
      !problem.empty()) {
    err << "blockmap: run: " << problem << '\n';
    return kExitFailure;
  }
  session->report(err, simulated->simulation().elapsed_s());
  err << "run: open " << (std::filesystem::path(options.mapping.out) / "map.wrl").string()
      << " in a VRML viewer (view3dscene, MeshLab), top_view.svg in a browser, or read "
         "planes.json\n";
  return kExitOk;
}

}  // namespace

Command add_run_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "run",
      "The onboard mapper; with no robot attached, on the built-in simulated city block "
      "(usc_block): writes planes.jsonl, planes.bin, buildings.jsonl, trajectory.csv, planes.json, "
      "buildings.json, map.wrl, top_view.svg, footprints.geojson");
  auto options = std::make_shared<RunOptions>();
  options->mapping.out = "out/run";
  command->add_option("--config", options->mapping.config,
                      "a TOML file: [planes] the detector, [buildings] the fitter, [window], "
                      "[projection], [mapper] and [free_space] the map; [robot], [devices] and "
                      "[daemon] the robot to map "
                      "from (config/README.md)");
  command->add_option("--out", options->mapping.out, "the folder to write into")
      ->capture_default_str();
  command->add_option("--world", options->world, "the simulated world (built-in name or .toml)")
      ->capture_default_str();
  command->add_option("--robot", options->robot, "the simulated robot (built-in name or .toml)")
      ->capture_default_str();
  command->add_option("--seed", options->seed, "the simulation's seed")->capture_default_str();
  command
      ->add_option("--duration-s", options->duration_s,
                   "stop after this much simulated time (0: the whole path)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command
      ->add_option("--poses", options->poses,
                   "filter: the particle filter's poses (as on the robot); truth: the "
                   "simulation's true poses")
      ->capture_default_str();
  add_udp_option(*command, options->mapping.udp);
  add_budget_option(*command, options->mapping.budget_mib);
  command->add_flag("--cloud", options->mapping.cloud,
                    "also write cloud.ply, every projected point");
  command
      ->add_option("--gps-silent-s", options->gps_silent_s,
                   "FROM TO: the simulated GPS receiver sends nothing between these seconds of "
                   "the run (a fault test)")
      ->expected(2)
      ->check(CLI::NonNegativeNumber);
  command->add_option("--laps", options->laps, "drive a loop path this many times")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  return {command, [options](std::ostream& /*out*/, std::ostream& err) {
            try {
              return run(*options, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: run: " << error.what() << '\n';
              return kExitUsage;
            }
          }};
}

}  // namespace blockmap::cli
