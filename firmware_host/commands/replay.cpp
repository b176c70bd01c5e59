// `blockmap replay DIR [--out DIR2]`: the onboard pipeline over recorded device logs
// (ARCHITECTURE.md 4.3-4.5, docs/log-formats.md). The recorded CAN frames and NMEA bytes go
// through the same device layer as on the robot (SegwayBase, GpsReceiver) over log-backed
// ports, in time order, into the localizer. This increment writes trajectory.csv: the
// smoothed poses in the local frame (ARCHITECTURE.md 4.4); the planes and buildings arrive
// with the streaming pipeline.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/hal/replay/log_ports.hpp"
#include "blockmap/hal/sim/robot.hpp"
#include "blockmap/localize/localizer.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"
#include "commands/geodetic_option.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;
using localize::GpsOutcome;
using localize::Pose3;

struct ReplayOptions {
  std::string dir;
  std::string out;
  std::string origin;  // "LAT,LON,H"; empty: the first good fix
  std::uint64_t seed = 1;
  std::size_t particles = localize::LocalizeConfig{}.particle_count;
};

constexpr TimestampNs kDayNs = 86'400 * kNanosecondsPerSecond;

// The fix's UTC on the log's clock. With a date (RMC), exact; without one (GGA alone), the
// day that puts it nearest to `near_ns` (the odometry's time), which survives midnight.
TimestampNs fix_stamp_ns(const msg::GpsFix& fix, TimestampNs near_ns) {
  const TimestampNs of_day_ns = static_cast<TimestampNs>(fix.utc_milliseconds_of_day) * 1'000'000;
  if (fix.has_date) {
    const std::chrono::sys_days day = std::chrono::year_month_day(std::chrono::year(fix.utc_year),
                                                                  std::chrono::month(fix.utc_month),
                                                                  std::chrono::day(fix.utc_day));
    return static_cast<TimestampNs>(day.time_since_epoch().count()) * kDayNs + of_day_ns;
  }
  const TimestampNs day_start = near_ns - near_ns % kDayNs;
  TimestampNs stamp = day_start + of_day_ns;
  if (stamp - near_ns > kDayNs / 2) {
    stamp -= kDayNs;
  } else if (near_ns - stamp > kDayNs / 2) {
    stamp += kDayNs;
  }
  return stamp;
}

hal::GeodeticPoint fix_point(const msg::GpsFix& fix) {
  // Ellipsoidal height: NMEA gives the height above the geoid and the geoid's separation.
  return {fix.latitude_deg, fix.longitude_deg,
          fix.altitude_msl_m + (fix.has_geoid_separation ? fix.geoid_separation_m : 0.0)};
}

// The recorded devices, read in time order.
class RecordedRun {
 public:
  RecordedRun(const fs::path& dir, const hal::devices::SegwayBaseConfig& base_config)
      : bus_((dir / "rmp.candump").string()),
        nmea_((dir / "gps.nmea").string()),
        base_(bus_, odometry_, imu_, base_config),
        gps_(nmea_, fixes_, hal::devices::GpsReceiverConfig{}) {
    static_cast<void>(base_.install_filters());
  }
  [[nodiscard]] std::string open_error() const {
    return !bus_.ok() ? bus_.error() : (!nmea_.ok() ? nmea_.error() : std::string());
  }
  // The next status group of the base; false at the end of its log.
  bool next_base(msg::OdometrySample& odometry, msg::ImuSample& imu) {
    while (odometry_.size_approx() == 0 && !base_done_) {
      base_done_ = base_.poll(0) == IoStatus::kClosed;
    }
    // The base publishes odometry and IMU together, one pair per group.
    return odometry_.try_pop(odometry) && imu_.try_pop(imu);
  }
  bool next_fix(msg::GpsFix& fix) {
    while (fixes_.size_approx() == 0 && !gps_done_) {
      const IoStatus status = gps_.poll(0);
      gps_done_ = status == IoStatus::kClosed || status == IoStatus::kIoError;
    }
    return fixes_.try_pop(fix);
  }
  [[nodiscard]] const hal::replay::CandumpFileBus& bus() const { return bus_; }
  [[nodiscard]] const hal::devices::GpsReceiver& gps() const { return gps_; }

 private:
  hal::replay::CandumpFileBus bus_;
  hal::replay::FileByteStream nmea_;
  SpscQueue<msg::OdometrySample, 64> odometry_;
  SpscQueue<msg::ImuSample, 64> imu_;
  SpscQueue<msg::GpsFix, 16> fixes_;
  hal::devices::SegwayBase base_;
  hal::devices::GpsReceiver gps_;
  bool base_done_ = false;
  bool gps_done_ = false;
};

class TrajectoryWriter {
 public:
  explicit TrajectoryWriter(std::ostream& out) : out_(out) {
    out_ << "t_s,x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad\n";
  }
  void write(std::span<const Pose3> poses) {
    for (const Pose3& p : poses) {
      char line[160];
      const int n = std::snprintf(line, sizeof line, "%.6f,%.4f,%.4f,%.4f,%.6f,%.6f,%.6f\n",
                                  seconds_from_ns(p.stamp_ns), p.x_m, p.y_m, p.z_m, p.roll_rad,
                                  p.pitch_rad, p.yaw_rad);
      out_.write(line, n);
      ++rows_;
    }
  }
  [[nodiscard]] std::size_t rows() const { return rows_; }

 private:
  std::ostream& out_;
  std::size_t rows_ = 0;
};

struct FixCounts {
  std::size_t used = 0;
  std::size_t rejected = 0;
  std::size_t recovered = 0;
  std::size_t without_position = 0;
};

int replay(const ReplayOptions& options, std::ostream& out, std::ostream& err) {
  const fs::path dir(options.dir);
  if (!fs::is_directory(dir)) {
    err << "blockmap: replay: " << options.dir << " is not a folder of device logs\n";
    return kExitFailure;
  }
  // The robot's configuration, when the log carries it (simulated runs and our logger do).
  hal::devices::SegwayBaseConfig base_config;
  localize::LocalizerConfig config;
  config.filter.particle_count = options.particles;
  config.filter.seed = options.seed;
  if (fs::exists(dir / "robot.toml")) {
    const hal::sim::RobotSpec robot = hal::sim::load_robot((dir / "robot.toml").string());
    base_config.rmp.model = robot.base.model;
    base_config.rmp.yaw_sign = robot.base.yaw_sign;
    config.antenna_height_m = robot.gps.antenna_m.z();
  }
  std::optional<hal::LocalEnuFrame> frame;
  if (!options.origin.empty()) {
    const std::optional<hal::GeodeticPoint> origin = parse_origin(options.origin);
    if (!origin) {
      err << "blockmap: replay: " << kOriginFormatError << '\n';
      return kExitUsage;
    }
    frame.emplace(*origin);
  }
  if (const std::string problem = localize::validate(config); !problem.empty()) {
    err << "blockmap: replay: " << problem << '\n';
    return kExitUsage;
  }

  auto run = std::make_unique<RecordedRun>(dir, base_config);
  if (const std::string problem = run->open_error(); !problem.empty()) {
    err << "blockmap: replay: " << problem << '\n';
    return kExitFailure;
  }
  Arena arena(localize::Localizer::arena_bytes(config));
  localize::Localizer localizer;
  localizer.init(arena, config);
  arena.seal();

  std::unique_ptr<std::ofstream> file;
  std::ostream* trajectory_out = &out;
  if (!options.out.empty()) {
    std::error_code error;
    fs::create_directories(options.out, error);
    file = std::make_unique<std::ofstream>(fs::path(options.out) / "trajectory.csv");
    if (error || !*file) {
      err << "blockmap: replay: cannot write " << (fs::path(options.out) / "trajectory.csv")
          << '\n';
      return kExitFailure;
    }
    trajectory_out = file.get();
  }
  TrajectoryWriter writer(*trajectory_out);
  std::vector<Pose3> poses(config.filter.history_steps);

  // Merge the two logs by time: each step takes whichever device's next message is older.
  msg::OdometrySample odometry;
  msg::ImuSample imu;
  msg::GpsFix fix;
  bool have_base = run->next_base(odometry, imu);
  bool have_fix = run->next_fix(fix);
  TimestampNs now_ns = have_base ? odometry.header.stamp_ns : 0;
  FixCounts counts;
  while (have_base || have_fix) {
    const bool usable_fix = have_fix && fix.valid && fix.has_position && fix.has_time;
    if (have_fix && !usable_fix) {
      ++counts.without_position;
      have_fix = run->next_fix(fix);
      continue;
    }
    const TimestampNs fix_ns = have_fix ? fix_stamp_ns(fix, now_ns) : 0;
    if (have_base && (!have_fix || odometry.header.stamp_ns <= fix_ns)) {
      now_ns = odometry.header.stamp_ns;
      localizer.on_base(odometry, imu);
      have_base = run->next_base(odometry, imu);
    } else {
      if (!frame) {
        frame.emplace(fix_point(fix));  // the local frame: anchored at the first good fix
      }
      const Eigen::Vector3d enu = frame->to_enu_m(fix_point(fix));
      const bool differential = fix.quality == msg::GpsFixQuality::kDgps ||
                                fix.quality == msg::GpsFixQuality::kRtkFixed ||
                                fix.quality == msg::GpsFixQuality::kRtkFloat;
      const localize::GpsObservation observation{fix_ns, enu.x(), enu.y(),
                                                 fix.has_hdop ? fix.hdop : 1.0, differential};
      switch (localizer.on_fix(observation, enu.z())) {
        case GpsOutcome::kRejected:
          ++counts.rejected;
          break;
        case GpsOutcome::kRecovered:
          ++counts.recovered;
          break;
        default:
          ++counts.used;
          break;
      }
      have_fix = run->next_fix(fix);
    }
    writer.write(std::span<const Pose3>(poses.data(), localizer.drain_final(poses)));
  }
  writer.write(std::span<const Pose3>(poses.data(), localizer.smoothed_window(poses)));
  trajectory_out->flush();

  const localize::LocalizerCounters& c = localizer.counters();
  err << "replay: " << c.base_samples << " base samples, " << counts.used << " fixes used, "
      << counts.rejected << " left out as outliers, " << counts.recovered << " restarts, "
      << counts.without_position << " without a position; " << writer.rows() << " trajectory rows";
  if (c.odometry_jumps > 0 || c.stale_samples > 0) {
    err << "; " << c.odometry_jumps << " odometry resets, " << c.stale_samples << " stale samples";
  }
  if (run->bus().lines_rejected() > 0) {
    err << "; " << run->bus().lines_rejected() << " unreadable CAN log lines (first: line "
        << run->bus().first_rejected_line() << ")";
  }
  if (frame) {
    char origin[96];
    std::snprintf(origin, sizeof origin, "; origin %.7f,%.7f,%.2f", frame->origin().latitude_deg,
                  frame->origin().longitude_deg, frame->origin().height_m);
    err << origin;
  }
  err << '\n';
  if (writer.rows() == 0) {
    err << "blockmap: replay: no pose: the logs have no odometry, or no usable GPS fix\n";
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace

Command add_replay_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "replay",
      "Run the onboard pipeline over recorded device logs (rmp.candump, gps.nmea); writes "
      "trajectory.csv");
  auto options = std::make_shared<ReplayOptions>();
  command->add_option("DIR", options->dir, "the folder of device logs (docs/log-formats.md)")
      ->required();
  command->add_option("--out", options->out,
                      "the folder to write into (default: trajectory.csv to stdout)");
  command->add_option("--origin", options->origin,
                      "the local frame's origin as LAT,LON,HEIGHT (default: the first good fix)");
  command->add_option("--seed", options->seed, "the particle filter's seed")->capture_default_str();
  command->add_option("--particles", options->particles, "the particle filter's particle count")
      ->check(CLI::Range(std::size_t{2}, std::size_t{1} << 24))
      ->capture_default_str();
  return {command, [options](std::ostream& out, std::ostream& err) {
            try {
              return replay(*options, out, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: replay: " << error.what() << '\n';
              return kExitFailure;
            }
          }};
}

}  // namespace blockmap::cli
