// `blockmap play DIR --pty-dir PATH [--can IFACE] [--speed X]`: recorded device logs played
// onto real interfaces at their recorded pace (daemon/log_player.hpp): the lasers' and the GPS
// receiver's bytes onto pseudo-terminals linked at PATH/<name>, the Segway's frames onto a
// SocketCAN interface. For trying `blockmap run` with a [devices] table against recorded bytes,
// on the robot's computer or in the test rig, with nothing attached.
#include <CLI/CLI.hpp>
#include <atomic>
#include <memory>
#include <optional>
#include <ostream>
#include <string>

#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/linux/socket_can_bus.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"
#include "daemon/log_player.hpp"
#include "daemon/stop_signals.hpp"

namespace blockmap::cli {
namespace {

struct PlayOptions {
  std::string dir;
  std::string pty_dir;
  std::string can;
  double speed = 1.0;
};

class SocketCanSink final : public daemon::CanSink {
 public:
  std::string open(const std::string& interface) { return bus_.open(interface); }
  bool send(const hal::CanFrame& frame) override { return bus_.send(frame) == IoStatus::kOk; }

 private:
  hal::linux_backend::SocketCanBus bus_;
};

std::atomic<bool> play_stop{false};

extern "C" void on_play_signal(int /*signal*/) {
  play_stop.store(true);
}

int play(const PlayOptions& options, std::ostream& err) {
  std::optional<SocketCanSink> can;
  if (!options.can.empty()) {
    can.emplace();
    if (const std::string problem = can->open(options.can); !problem.empty()) {
      err << "blockmap: play: " << problem << '\n';
      return kExitFailure;
    }
  }
  daemon::LogPlayer player;
  if (const std::string problem =
          player.open(options.dir, options.pty_dir, can ? &*can : nullptr, options.speed);
      !problem.empty()) {
    err << "blockmap: play: " << problem << '\n';
    return kExitFailure;
  }
  for (const std::string& name : player.serial_names()) {
    err << "play: " << name << " on " << player.link_of(name).string() << '\n';
  }
  if (can) {
    err << "play: rmp.candump onto " << options.can << '\n';
  }
  err.flush();
  play_stop.store(false);
  double played_s = 0.0;
  {
    const daemon::StopSignals stop_signals(on_play_signal);
    played_s = player.play(play_stop);
  }
  const daemon::PlayerCounters c = player.counters();
  err << "play: " << played_s << " s of logs: " << c.serial_bytes << " serial bytes ("
      << c.serial_discarded << " with nobody reading), " << c.can_frames << " CAN frames ("
      << c.can_refused << " refused)\n";
  return kExitOk;
}

}  // namespace

Command add_play_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "play",
      "Play recorded device logs onto pseudo-terminals (and a CAN interface) at their recorded "
      "pace, for `blockmap run` with a [devices] table to map from");
  auto options = std::make_shared<PlayOptions>();
  command->add_option("DIR", options->dir, "the folder of device logs (docs/log-formats.md)")
      ->required();
  command
      ->add_option("--pty-dir", options->pty_dir,
                   "where the serial lines' ends are linked, one per log (laser_<name>, gps)")
      ->required();
  command->add_option("--can", options->can, "also play rmp.candump onto this SocketCAN interface");
  command->add_option("--speed", options->speed, "times the recorded pace")
      ->check(CLI::Range(0.01, 100.0))
      ->capture_default_str();
  return {command, [options](std::ostream& /*out*/, std::ostream& err) {
            try {
              return play(*options, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: play: " << error.what() << '\n';
              return kExitFailure;
            }
          }};
}

}  // namespace blockmap::cli
