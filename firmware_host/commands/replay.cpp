// `blockmap replay DIR [--out DIR2]`: the onboard pipeline over recorded device logs
// (docs/formats.md, command line; docs/log-formats.md). The recorded CAN frames, NMEA bytes and
// laser telegrams go through the same device layer as on the robot (SegwayBase, GpsReceiver,
// Lms2xxScanner) over log-backed ports, merged in time order, into the mapper
// (pipeline::Mapper): with --out it writes what `run` writes (docs/formats.md, run outputs),
// without it the smoothed trajectory to stdout. Laser logs are read when robot.toml names the
// lasers.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <ostream>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/gps_observations.hpp"
#include "blockmap/hal/replay/log_ports.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"
#include "commands/geodetic_option.hpp"
#include "commands/mapping.hpp"
#include "commands/prior_map_file.hpp"
#include "commands/recorded_run.hpp"
#include "commands/truth_trajectory.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;

struct ReplayOptions {
  std::string dir;
  MappingOptions mapping;  // out, config, udp, budget
  std::string origin;      // "LAT,LON,H"; empty: the first good fix
  std::string start_pose;  // "X,Y,YAW_DEG" in the local frame: a robot without a receiver
  // GeoJSON, buildings.json or planes.json, one or more: localize against their walls too
  std::vector<std::string> prior_maps;
  std::string poses = "filter";  // or "truth": a simulated run's true poses (truth.json)
  std::uint64_t seed = 1;
  std::size_t particles = pipeline::MapperConfig{}.localizer.filter.particle_count;
};

// "X,Y,YAW_DEG": three finite numbers.
std::optional<localize::Pose2> parse_start_pose(const std::string& text) {
  const std::optional<std::array<double, 3>> values = parse_three_numbers(text);
  if (!values || !std::isfinite((*values)[0]) || !std::isfinite((*values)[1]) ||
      !std::isfinite((*values)[2])) {
    return std::nullopt;
  }
  return localize::Pose2{0, (*values)[0], (*values)[1], radians_from_degrees((*values)[2])};
}

// truth.json's trajectory: a simulated run's true poses, oldest first (the ceiling of what
// the logs map to: the same scans drawn without the localizer's error).
std::vector<localize::Pose3> read_true_poses(const fs::path& path, std::string& problem) {
  std::vector<localize::Pose3> poses;
  std::ifstream file(path);
  if (!file) {
    problem = path.string() + " cannot be read (--poses truth takes a simulated run's logs)";
    return poses;
  }
  try {
    poses = true_poses_of(nlohmann::json::parse(file));
  } catch (const nlohmann::json::exception& error) {
    problem = path.string() + ": not a truth.json (" + error.what() + ")";
    return {};
  }
  const auto older = [](const localize::Pose3& a, const localize::Pose3& b) {
    return a.stamp_ns < b.stamp_ns;
  };
  if (poses.empty() || !std::is_sorted(poses.begin(), poses.end(), older)) {
    problem = path.string() + ": its trajectory is empty or not in time order";
    return {};
  }
  return poses;
}

// Localization only: no lasers, and the map's capacities at their smallest.
void shrink_to_localization(pipeline::MapperConfig& config) {
  config.laser_count = 0;
  config.window.max_samples = 64;
  config.planes.max_blocks = 64;
  config.planes.max_samples_per_section = 64;
  config.planes.max_patches = 16;
  config.planes.max_planes = 16;
  config.registry.max_live_planes = 1;
  config.registry.max_final_planes = 1;
  config.scan_queue_capacity = 1;
}

// The logs' next messages, handed to the mapper oldest first.
class TimeMerge {
 public:
  // `true_poses`, when not empty, go to the mapper too (PoseSource::kExternal).
  TimeMerge(RecordedRun& run, hal::FixConverter& fixes, std::span<const localize::Pose3> true_poses)
      : run_(run),
        fixes_(fixes),
        true_poses_(true_poses),
        scans_(run.laser_count()),
        have_scan_(run.laser_count()) {
    have_base_ = run_.next_base(odometry_, imu_);
    now_ns_ = have_base_ ? odometry_.header.stamp_ns : 0;
    next_usable_fix();
    for (std::size_t i = 0; i < scans_.size(); ++i) {
      scans_[i] = std::make_unique<msg::LaserScan>();
      have_scan_[i] = run_.next_scan(i, *scans_[i]);
    }
  }
  // Whether the base's log has a status group at all.
  [[nodiscard]] bool has_base() const noexcept { return have_base_; }
  // The span of the messages handed over, s.
  [[nodiscard]] double span_s() const noexcept {
    return last_ns_ > first_ns_ ? seconds_from_ns(last_ns_ - first_ns_) : 0.0;
  }
  // Hands the oldest message to `mapper`; false when every log is done.
  bool feed_next(pipeline::Mapper& mapper) {
    constexpr TimestampNs kNever = std::numeric_limits<TimestampNs>::max();
    const TimestampNs base_ns = have_base_ ? odometry_.header.stamp_ns : kNever;
    const TimestampNs fix_ns = have_fix_ ? observation_.stamp_ns : kNever;
    const TimestampNs pose_ns =
        next_pose_ < true_poses_.size() ? true_poses_[next_pose_].stamp_ns : kNever;
    std::size_t laser = scans_.size();
    TimestampNs scan_ns = kNever;
    for (std::size_t i = 0; i < scans_.size(); ++i) {
      if (have_scan_[i] && scans_[i]->header.stamp_ns < scan_ns) {
        scan_ns = scans_[i]->header.stamp_ns;
        laser = i;
      }
    }
    const TimestampNs oldest_ns = std::min({base_ns, fix_ns, scan_ns, pose_ns});
    if (oldest_ns == kNever) {
      return false;
    }
    if (pose_ns == oldest_ns) {
      mapper.on_pose(true_poses_[next_pose_++]);
      return true;
    }
    first_ns_ = std::min(first_ns_, oldest_ns);
    last_ns_ = std::max(last_ns_, oldest_ns);
    if (base_ns <= fix_ns && base_ns <= scan_ns) {
      now_ns_ = base_ns;
      mapper.on_base(odometry_, imu_);
      have_base_ = run_.next_base(odometry_, imu_);
    } else if (fix_ns <= scan_ns) {
      mapper.on_fix(observation_, up_m_);
      next_usable_fix();
    } else {
      static_cast<void>(mapper.on_scan(laser, *scans_[laser]));
      have_scan_[laser] = run_.next_scan(laser, *scans_[laser]);
    }
    return true;
  }

 private:
  void next_usable_fix() {
    msg::GpsFix fix;
    have_fix_ = false;
    while (run_.next_fix(fix)) {
      if (fixes_.convert(fix, now_ns_, observation_, up_m_)) {
        have_fix_ = true;
        return;
      }
    }
  }

  RecordedRun& run_;
  hal::FixConverter& fixes_;
  std::span<const localize::Pose3> true_poses_;
  std::size_t next_pose_ = 0;
  msg::OdometrySample odometry_;
  msg::ImuSample imu_;
  bool have_base_ = false;
  localize::GpsObservation observation_;
  double up_m_ = 0.0;
  bool have_fix_ = false;
  TimestampNs now_ns_ = 0;
  std::vector<std::unique_ptr<msg::LaserScan>> scans_;
  std::vector<bool> have_scan_;
  TimestampNs first_ns_ = std::numeric_limits<TimestampNs>::max();
  TimestampNs last_ns_ = 0;
};

// "; N times off both neighbours (given the time before), M clock steps or gaps kept"
void report_times(std::ostream& err, const char* what, const hal::replay::RecordedTimes& times) {
  if (times.faults() > 0 || times.steps() > 0) {
    err << "; " << what << " times: " << times.faults()
        << " off both neighbours (given the time before), " << times.steps()
        << " steps or gaps of over 0.25 s kept";
  }
}

int replay(const ReplayOptions& options, std::ostream& out, std::ostream& err) {
  const fs::path dir(options.dir);
  if (!fs::is_directory(dir)) {
    err << "blockmap: replay: " << options.dir << " is not a folder of device logs\n";
    return kExitFailure;
  }
  // The robot's configuration, when the log carries it (simulated runs and our logger do).
  hal::devices::SegwayBaseConfig base_config;
  hal::config::RobotSpec robot;
  pipeline::MapperConfig config;
  const bool map_planes = !options.mapping.out.empty() && !options.mapping.trajectory_only;
  const bool robot_recorded = fs::exists(dir / "robot.toml");
  if (robot_recorded) {
    // The log's own file: a fault in it is the data's (1), not the command line's.
    try {
      robot = hal::config::load_robot((dir / "robot.toml").string());
      hal::config::require_lms2xx_lasers(robot, "the replay of byte logs");
    } catch (const hal::ConfigError& error) {
      err << "blockmap: replay: " << error.what() << '\n';
      return kExitFailure;
    }
    base_config = hal::config::segway_base_config_for(robot);
    // A laser the logger did not record (an import from odometry and GPS), or whose log cannot
    // be read as one, is left out: the run goes on without it.
    std::erase_if(robot.lasers, [&](const hal::config::LaserSpec& laser) {
      const fs::path log = dir / ("laser_" + laser.name + ".bytelog");
      if (!fs::exists(log)) {
        if (map_planes) {
          err << "replay: no laser_" << laser.name << ".bytelog: mapping without that laser\n";
        }
        return true;
      }
      if (const hal::replay::ByteLogFileStream stream(log.string()); !stream.ok()) {
        if (map_planes) {
          err << "replay: warning: " << stream.error() << ": mapping without that laser\n";
        }
        return true;
      }
      return false;
    });
    config = hal::config::mapper_config_for(robot);
  }
  config = with_config_file(config, options.mapping);
  if (!robot_recorded && map_planes) {
    err << "replay: warning: no robot.toml in " << options.dir
        << ": the lasers' mounts are unknown, so no laser log is read (the trajectory only)\n";
  }
  config.localizer.filter.particle_count = options.particles;
  config.localizer.filter.seed = options.seed;
  // Without --out, or asked to, only the trajectory is wanted: the lasers are not read.
  if (!map_planes) {
    robot.lasers.clear();
    shrink_to_localization(config);
  }
  std::optional<hal::FixConverter> fixes;
  if (!options.origin.empty()) {
    const std::optional<hal::GeodeticPoint> origin = parse_origin(options.origin);
    if (!origin) {
      err << "blockmap: replay: " << kOriginFormatError << '\n';
      return kExitUsage;
    }
    fixes.emplace(*origin);
  } else {
    fixes.emplace();
  }
  if (!options.start_pose.empty()) {
    const std::optional<localize::Pose2> start = parse_start_pose(options.start_pose);
    if (!start || options.origin.empty()) {
      err << "blockmap: replay: --start-pose takes X,Y,YAW_DEG (metres east and north of "
             "--origin, which it needs, and degrees from east)\n";
      return kExitUsage;
    }
    config.localizer.start_at_known_pose = true;
    config.localizer.start_pose = *start;
  }
  std::vector<localize::MapWall> prior_walls;
  if (!options.prior_maps.empty()) {
    if (options.origin.empty() || !map_planes) {
      err << "blockmap: replay: --prior-map needs --origin (where the map lies on Earth) and "
             "--out\n";
      return kExitUsage;
    }
    for (const std::string& path : options.prior_maps) {
      std::string problem;
      const std::vector<localize::MapWall> walls = read_prior_map(path, *fixes->frame(), problem);
      if (!problem.empty()) {
        err << "blockmap: replay: --prior-map: " << problem << '\n';
        return kExitUsage;
      }
      prior_walls.insert(prior_walls.end(), walls.begin(), walls.end());
    }
    config.prior_map.enabled = true;
    config.prior_map.seed = options.seed;
  }
  std::vector<localize::Pose3> true_poses;
  if (options.poses == "truth") {
    if (!map_planes || !options.prior_maps.empty() || !options.start_pose.empty()) {
      err << "blockmap: replay: --poses truth maps (--out) with the true poses alone: no "
             "--prior-map or --start-pose\n";
      return kExitUsage;
    }
    std::string problem;
    true_poses = read_true_poses(dir / "truth.json", problem);
    if (!problem.empty()) {
      err << "blockmap: replay: " << problem << '\n';
      return kExitFailure;
    }
    config.pose_source = pipeline::PoseSource::kExternal;
  } else if (options.poses != "filter") {
    err << "blockmap: replay: --poses is filter or truth\n";
    return kExitUsage;
  }
  if (const std::string problem = pipeline::validate(config); !problem.empty()) {
    err << "blockmap: replay: " << problem << '\n';
    return kExitUsage;
  }
  auto run = std::make_unique<RecordedRun>(dir, base_config, robot.lasers,
                                           config.localizer.start_at_known_pose);
  if (const std::string problem = run->open_error(); !problem.empty()) {
    err << "blockmap: replay: " << problem << '\n';
    return kExitFailure;
  }
  auto session = std::make_unique<MappingSession>();
  // The memory report only when mapping: a trajectory alone is a quiet job.
  std::ostringstream quiet;
  if (const std::string problem = session->start(config, options.mapping, map_planes ? err : quiet);
      !problem.empty()) {
    err << "blockmap: replay: " << problem << '\n';
    return kExitUsage;
  }
  if (const std::string problem = session->open_outputs(options.mapping, out); !problem.empty()) {
    err << "blockmap: replay: " << problem << '\n';
    return kExitFailure;
  }
  if (!prior_walls.empty()) {
    if (const std::string problem = session->mapper().set_prior_map(prior_walls);
        !problem.empty()) {
      err << "blockmap: replay: --prior-map: " << problem << '\n';
      return kExitUsage;
    }
  }

  TimeMerge merge(*run, *fixes, true_poses);
  if (!merge.has_base() && true_poses.empty()) {
    // The localizer moves the robot by its wheels: without them nothing can be placed.
    err << "blockmap: replay: rmp.candump holds no status group of the base: nothing to map "
           "from\n";
    return kExitFailure;
  }
  while (merge.feed_next(session->mapper())) {
    session->pump();
  }
  std::optional<hal::GeodeticPoint> origin;
  if (fixes->frame()) {
    origin = fixes->frame()->origin();
  }
  if (const std::string problem = session->finish(origin); !problem.empty()) {
    err << "blockmap: replay: " << problem << '\n';
    return kExitFailure;
  }

  const pipeline::MapperCounters& c = session->mapper().counters();
  const localize::LocalizerCounters& lc = session->mapper().localizer().counters();
  const std::uint64_t used = c.fixes - c.fixes_rejected - c.fixes_recovered;
  err << "replay: " << c.base_samples << " base samples, " << used << " fixes used, "
      << c.fixes_rejected << " left out as outliers, " << c.fixes_recovered << " restarts, "
      << fixes->without_position() << " without a position; "
      << session->outputs().trajectory_rows() << " trajectory rows";
  if (lc.odometry_jumps > 0 || lc.stale_samples > 0) {
    err << "; " << lc.odometry_jumps << " odometry resets, " << lc.stale_samples
        << " stale samples";
  }
  if (run->bus().lines_rejected() > 0) {
    err << "; " << run->bus().lines_rejected() << " unreadable CAN log lines (first: line "
        << run->bus().first_rejected_line() << ")";
  }
  report_times(err, "CAN log", run->bus().times());
  if (fixes->frame()) {
    char origin_text[96];
    std::snprintf(origin_text, sizeof origin_text, "; origin %.7f,%.7f,%.2f",
                  fixes->frame()->origin().latitude_deg, fixes->frame()->origin().longitude_deg,
                  fixes->frame()->origin().height_m);
    err << origin_text;
  }
  err << '\n';
  if (map_planes) {
    session->report(err, merge.span_s());
  }
  bool damaged = false;
  for (std::size_t i = 0; i < run->laser_count(); ++i) {
    const hal::replay::ByteLogFileStream& log = run->laser_log(i);
    if (log.skipped_places() > 0 || log.times().faults() > 0 || log.times().steps() > 0) {
      err << "replay: warning: laser_" << robot.lasers[i].name
          << ".bytelog: " << log.skipped_places() << " damaged places skipped ("
          << log.skipped_bytes() << " bytes; the first at byte " << log.first_skip_offset() << ": "
          << hal::protocol::byte_log::to_string(log.first_skip()) << ")";
      report_times(err, "its", log.times());
      err << '\n';
    }
    if (log.damage() != hal::protocol::byte_log::ParseError::kNone) {
      err << "blockmap: replay: laser_" << robot.lasers[i].name << ".bytelog is damaged at byte "
          << log.damage_offset() << " (" << hal::protocol::byte_log::to_string(log.damage())
          << "): the scans before it were mapped\n";
      damaged = true;
    }
  }
  if (session->outputs().trajectory_rows() == 0) {
    err << "blockmap: replay: no pose: gps.nmea holds no usable fix (--origin and --start-pose "
           "place the robot without one)\n";
    return kExitFailure;
  }
  return damaged ? kExitFailure : kExitOk;
}

}  // namespace

Command add_replay_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "replay",
      "Run the onboard pipeline over recorded device logs (rmp.candump, gps.nmea, "
      "laser_<name>.bytelog): writes what run writes");
  auto options = std::make_shared<ReplayOptions>();
  command->add_option("DIR", options->dir, "the folder of device logs (docs/log-formats.md)")
      ->required();
  command->add_option("--out", options->mapping.out,
                      "the folder to write into (default: only trajectory.csv, to stdout)");
  command->add_option("--config", options->mapping.config,
                      "a TOML file: [planes] the detector, [buildings] the fitter, [window] and "
                      "[projection] the map (config/README.md)");
  add_udp_option(*command, options->mapping.udp);
  add_budget_option(*command, options->mapping.budget_mib);
  command->add_flag("--cloud", options->mapping.cloud,
                    "also write cloud.ply, every projected point");
  command->add_flag("--trajectory-only", options->mapping.trajectory_only,
                    "localize only: write trajectory.csv, read no laser log");
  command->add_option("--origin", options->origin,
                      "the local frame's origin as LAT,LON,HEIGHT (default: the first good fix)");
  command->add_option("--prior-map", options->prior_maps,
                      "localize against this map too (Monte Carlo): footprints as GeoJSON in "
                      "WGS-84, or an earlier run's buildings.json or planes.json (its walls "
                      "seen); given more than once, their walls together; needs --origin");
  command->add_option("--start-pose", options->start_pose,
                      "X,Y,YAW_DEG: a robot without a receiver starts here in the local frame of "
                      "--origin (gps.nmea may then be missing)");
  command
      ->add_option("--poses", options->poses,
                   "filter: the particle filter's poses (as on the robot); truth: a simulated "
                   "run's true poses, from truth.json in DIR")
      ->capture_default_str();
  command->add_option("--seed", options->seed, "the particle filter's seed")->capture_default_str();
  command->add_option("--particles", options->particles, "the particle filter's particle count")
      ->check(CLI::Range(std::size_t{2}, std::size_t{1} << 24))
      ->capture_default_str();
  return {command, [options](std::ostream& out, std::ostream& err) {
            try {
              return replay(*options, out, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: replay: " << error.what() << '\n';
              return kExitUsage;
            }
          }};
}

}  // namespace blockmap::cli
