// Each subcommand registers itself on the application: its options, and the function that runs
// it after parsing. Only subcommands that really work are registered.
#pragma once

#include <functional>
#include <iosfwd>

namespace CLI {
class App;
}

namespace blockmap::cli {

// Runs the parsed subcommand; returns its exit status.
using CommandAction = std::function<int(std::ostream& out, std::ostream& err)>;

struct Command {
  CLI::App* subcommand;  // owned by the parent application
  CommandAction action;
};

// `blockmap info`: what this binary is and what the machine under it offers.
Command add_info_command(CLI::App& app);

// `blockmap decode PROTOCOL FILE`: a raw capture as JSON Lines.
Command add_decode_command(CLI::App& app);

// `blockmap planes CLOUD`: the plane list of a point cloud file.
Command add_planes_command(CLI::App& app);

// `blockmap buildings INPUT`: the buildings of a plane list or a point cloud file.
Command add_buildings_command(CLI::App& app);

// `blockmap simulate --world NAME --out DIR`: a recorded run of the simulated robot.
Command add_simulate_command(CLI::App& app);
// `blockmap run [--config FILE] [--out DIR]`: the onboard mapper (the simulated city block).
Command add_run_command(CLI::App& app);
// `blockmap replay DIR [--out DIR2]`: the onboard pipeline over recorded device logs.
Command add_replay_command(CLI::App& app);
// `blockmap play DIR --pty-dir PATH`: recorded device logs onto pseudo-terminals and CAN.
Command add_play_command(CLI::App& app);
// `blockmap score MAP TRUTH`: a map of a simulated run against the run's truth.
Command add_score_command(CLI::App& app);
// `blockmap import TRAJECTORY --origin ... --out DIR`: device logs from a reference trajectory.
Command add_import_command(CLI::App& app);

}  // namespace blockmap::cli
