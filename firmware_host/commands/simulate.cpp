// `blockmap simulate --world NAME [--robot NAME] [--seed N] --out DIR [--cloud FILE.ply]`: a
// recorded run of the simulated robot (docs/formats.md, ground truth): the devices' raw logs,
// exactly as the robot's logger would write them, and the ground truth. The same seed gives the
// same bytes. --cloud also writes every laser return along the true trajectory (the cloud a
// perfect localisation would give) as a PLY file, for `blockmap planes` and other tools.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "blockmap/hal/cloud/point_cloud_file.hpp"
#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/run_recorder.hpp"
#include "blockmap/hal/sim/simulation.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"
#include "outputs/building_outputs.hpp"

namespace blockmap::cli {
namespace {

struct SimulateOptions {
  std::string world;
  std::string robot = "paper_rmp";
  std::uint64_t seed = 1;
  double duration_s = 0.0;
  std::string out;
  std::string cloud;
  std::vector<double> gps_silent_s;  // FROM,TO: the receiver sends nothing between
  std::vector<double> gps_jumps;     // FRACTION,METRES: fixes off by a multipath jump
};

// The recorder's events, and the beams also to the truth cloud.
class RecorderAndCloud : public hal::sim::SimSink {
 public:
  RecorderAndCloud(hal::sim::SimSink& recorder, hal::sim::SimSink* cloud)
      : recorder_(recorder), cloud_(cloud) {}
  void on_can_frame(TimestampNs stamp_ns, const hal::CanFrame& frame) override {
    recorder_.on_can_frame(stamp_ns, frame);
  }
  void on_serial(std::size_t device, TimestampNs stamp_ns,
                 hal::protocol::byte_log::Direction direction,
                 std::span<const std::uint8_t> bytes) override {
    recorder_.on_serial(device, stamp_ns, direction, bytes);
  }
  void on_truth_state(TimestampNs stamp_ns, const hal::sim::RobotState& state) override {
    recorder_.on_truth_state(stamp_ns, state);
  }
  void on_beam(std::size_t laser, const hal::sim::BeamTruth& beam) override {
    recorder_.on_beam(laser, beam);
    if (cloud_ != nullptr) {
      cloud_->on_beam(laser, beam);
    }
  }
  void on_gps_epoch(const hal::sim::GpsTruth& truth) override { recorder_.on_gps_epoch(truth); }

 private:
  hal::sim::SimSink& recorder_;
  hal::sim::SimSink* cloud_;
};

// The world's buildings as GeoJSON in WGS-84: a prior map from a GIS layer
// (`replay --prior-map`).
std::string truth_footprints(const hal::sim::World& world) {
  const hal::LocalEnuFrame frame(world.site.origin);
  nlohmann::json features = nlohmann::json::array();
  for (const hal::sim::Building& building : world.buildings) {
    features.push_back(footprint_feature(building.footprint_m, 0.0, frame,
                                         {{"id", building.id},
                                          {"shape", hal::sim::to_string(building.shape)},
                                          {"height_m", building.height_m}}));
  }
  return nlohmann::json{{"type", "FeatureCollection"}, {"features", features}}.dump();
}

int simulate(const SimulateOptions& options, std::ostream& err) {
  std::string world_source;
  std::string robot_source;
  const std::string world_text = hal::sim::world_text(options.world, world_source);
  const std::string robot_text = hal::config::robot_text(options.robot, robot_source);
  const hal::sim::World world = hal::sim::parse_world(world_text, world_source);
  const hal::config::RobotSpec robot = hal::config::parse_robot(robot_text, robot_source);
  hal::sim::SimOptions sim_options;
  sim_options.seed = options.seed;
  sim_options.max_duration_s = options.duration_s;
  if (!options.gps_silent_s.empty()) {
    sim_options.gps_silent_from_s = options.gps_silent_s[0];
    sim_options.gps_silent_to_s = options.gps_silent_s[1];
  }
  if (!options.gps_jumps.empty()) {
    sim_options.gps_jump_fraction = options.gps_jumps[0];
    sim_options.gps_jump_m = options.gps_jumps[1];
  }

  const auto wall_start = std::chrono::steady_clock::now();
  hal::sim::Simulation simulation(world, robot, sim_options);
  hal::sim::RunRecorder recorder(options.out, simulation);
  recorder.write_text_file("world.toml", world_text);
  recorder.write_text_file("robot.toml", robot_text);
  hal::sim::TruthCloudSink cloud;
  RecorderAndCloud sink(recorder, options.cloud.empty() ? nullptr : &cloud);
  simulation.run(sink);
  recorder.write_text_file("truth_footprints.geojson", truth_footprints(world) + '\n');
  recorder.finish(options.seed);
  if (!options.cloud.empty()) {
    hal::cloud::write_ply(options.cloud, cloud.points());
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();

  const hal::sim::SimStats& stats = simulation.stats();
  err << "simulate: " << world.name << " seed " << options.seed << ": " << simulation.elapsed_s()
      << " s, " << simulation.motion().distance_m() << " m driven, in " << wall_s << " s ("
      << simulation.elapsed_s() / wall_s << "x real time); ";
  for (std::size_t i = 0; i < robot.lasers.size(); ++i) {
    err << "laser " << robot.lasers[i].name << ' ' << stats.scans_sent[i] << " scans ("
        << stats.beams_returned[i] << " returns), ";
  }
  err << stats.gps_epochs << " GPS epochs (" << stats.gps_epochs_without_fix << " without fix, "
      << stats.gps_epochs_silent << " not sent), " << stats.rmp_cycles << " RMP cycles -> "
      << options.out << '\n';
  return kExitOk;
}

}  // namespace

Command add_simulate_command(CLI::App& app) {
  CLI::App* command =
      app.add_subcommand("simulate",
                         "Record a run of the simulated robot through a simulated city block: raw "
                         "device logs and truth.json");
  auto options = std::make_shared<SimulateOptions>();
  std::string worlds;
  for (const std::string_view name : hal::sim::builtin_world_names()) {
    worlds += worlds.empty() ? "" : ", ";
    worlds += name;
  }
  command
      ->add_option("--world", options->world,
                   "a built-in world (" + worlds + ") or a world .toml file")
      ->required();
  command
      ->add_option("--robot", options->robot, "a built-in robot (paper_rmp) or a robot .toml file")
      ->capture_default_str();
  command
      ->add_option("--seed", options->seed, "the run's random seed: the same seed, the same bytes")
      ->capture_default_str();
  command
      ->add_option("--duration-s", options->duration_s,
                   "stop after this much simulated time (0: drive the whole path)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--out", options->out, "the folder to write the logs into")->required();
  command->add_option("--cloud", options->cloud,
                      "also write every laser return along the true trajectory as a PLY file");
  // Faults of the receiver, for testing what the map keeps through them.
  command
      ->add_option("--gps-silent", options->gps_silent_s,
                   "FROM_S,TO_S: the receiver sends nothing between these times of the run")
      ->expected(2)
      ->delimiter(',')
      ->check(CLI::NonNegativeNumber);
  command
      ->add_option("--gps-jumps", options->gps_jumps,
                   "FRACTION,METRES: this share of the fixes off by a multipath jump of this "
                   "many metres, in a random direction")
      ->expected(2)
      ->delimiter(',')
      ->check(CLI::NonNegativeNumber);
  return {command, [options](std::ostream& /*out*/, std::ostream& err) {
            if (!options->gps_silent_s.empty() &&
                !(options->gps_silent_s[1] > options->gps_silent_s[0])) {
              err << "blockmap: simulate: --gps-silent takes FROM_S,TO_S with TO_S after FROM_S\n";
              return kExitUsage;
            }
            if (!options->gps_jumps.empty() &&
                !(options->gps_jumps[0] <= 1.0 && std::isfinite(options->gps_jumps[1]))) {
              err << "blockmap: simulate: --gps-jumps takes FRACTION,METRES with FRACTION at "
                     "most 1\n";
              return kExitUsage;
            }
            try {
              return simulate(*options, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: " << error.what() << '\n';
              return kExitUsage;
            } catch (const std::runtime_error& error) {
              err << "blockmap: " << error.what() << '\n';
              return kExitFailure;
            }
          }};
}

}  // namespace blockmap::cli
