// `blockmap import TRAJECTORY --origin LAT,LON,H --out DIR [--robot NAME] [--seed N]`: a
// reference trajectory of a real vehicle made into the device logs of a robot driving it
// (docs/log-formats.md), for `blockmap replay`. The motion is real; the sensors are the
// robot's models (hal/sim/sensor_models.hpp): the Segway's wheel counts with its tyre-pressure
// scale error and slip, its gyroscope with a bias, and GPS fixes with the receiver's error,
// all through the devices' encoders. truth.json holds the reference, so that the replay can
// be scored against it.
//
// TRAJECTORY is an MRPT odometry text export (`rawlog-edit --export-odometry-txt`): lines of
// time (Unix s), x, y, phi (m, m, rad) and further columns, '%' comments. The UAL loop of
// ../shared/data/real/ual-2dlaser-odo is one.
//
// With --scans SCANS (an MRPT 2D-scan text export, `rawlog-edit --export-2d-scans-txt`: time,
// N ranges in m, N valid flags per line) the recorded scans become the robot's first laser's
// telegrams (laser_<name>.bytelog, LMS2xx B0 measured values with their receive times): real
// ranges, the robot's laser mount (config/robots/ual_car.toml is the UAL vehicle's).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <optional>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "blockmap/core/angles.hpp"
#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/hal/protocol/byte_log.hpp"
#include "blockmap/hal/protocol/candump.hpp"
#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "blockmap/hal/sim/sensor_models.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"
#include "commands/decoders.hpp"
#include "commands/geodetic_option.hpp"

namespace blockmap::cli {
namespace {

namespace fs = std::filesystem;
namespace nmea = hal::protocol::nmea;
namespace rmp = hal::protocol::segway_rmp;

struct ImportOptions {
  std::string trajectory;
  std::string out;
  std::string origin;
  std::string scans;
  std::string robot = "paper_rmp";
  std::uint64_t seed = 1;
};

constexpr double kCycleS = 0.01;              // the RMP's 100 Hz status group
constexpr TimestampNs kFrameGapNs = 250'000;  // its eight frames, 250 us apart

struct ReferencePose {
  double t_s = 0.0;
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;     // unwrapped: continuous across +-pi
  double speed_mps = -1.0;  // the vehicle's own, when the export has it (MRPT: VEL_VX)
};

struct Reference {
  std::vector<ReferencePose> poses;
  std::size_t skipped_rows = 0;  // malformed, or not later than the row before

  // Linear between rows (rows are 10-20 ms apart).
  [[nodiscard]] ReferencePose at(double t_s) const {
    const auto later = std::lower_bound(poses.begin(), poses.end(), t_s,
                                        [](const ReferencePose& p, double t) { return p.t_s < t; });
    if (later == poses.begin()) {
      return poses.front();
    }
    if (later == poses.end()) {
      return poses.back();
    }
    const ReferencePose& a = *(later - 1);
    const ReferencePose& b = *later;
    const double f = (t_s - a.t_s) / (b.t_s - a.t_s);
    return {t_s, a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m),
            a.yaw_rad + f * (b.yaw_rad - a.yaw_rad)};
  }
};

// A logger stamps odometry rows when they arrive, and they arrive in bursts: on the UAL loop,
// rows 0.1 ms apart are 5 cm apart (500 m/s). Where the export has the vehicle's speed, each
// row's time is the previous one's plus its travel at that speed, pulled gently (5 % a row)
// towards the logged time, so the clock does not drift. Stopped, the logged time is kept.
void retime_by_speed(std::vector<ReferencePose>& poses) {
  constexpr double kPull = 0.05;
  constexpr double kMovingMps = 0.2;
  double previous_s = poses.front().t_s;
  for (std::size_t i = 1; i < poses.size(); ++i) {
    ReferencePose& pose = poses[i];
    const ReferencePose& before = poses[i - 1];
    if (pose.speed_mps < kMovingMps) {
      previous_s = std::max(pose.t_s, previous_s + 1e-4);
      pose.t_s = previous_s;
      continue;
    }
    const double travel_m = std::hypot(pose.x_m - before.x_m, pose.y_m - before.y_m);
    const double predicted_s = previous_s + travel_m / pose.speed_mps;
    previous_s = std::max(predicted_s + kPull * (pose.t_s - predicted_s), previous_s + 1e-4);
    pose.t_s = previous_s;
  }
}

Reference read_reference(const std::string& path) {
  std::ifstream file(path);
  if (!file) {
    throw std::runtime_error(path + ": cannot be read");
  }
  Reference reference;
  for (std::string line; std::getline(file, line);) {
    if (line.empty() || line.front() == '%' || line.front() == '#') {
      continue;
    }
    std::istringstream fields(line);
    ReferencePose pose;
    // MRPT's columns after phi: has_encoders, left and right ticks, has_velocities, vx, ...
    double has_encoders = 0.0;
    double left_ticks = 0.0;
    double right_ticks = 0.0;
    double has_velocities = 0.0;
    double vx = 0.0;
    const bool parsed =
        static_cast<bool>(fields >> pose.t_s >> pose.x_m >> pose.y_m >> pose.yaw_rad);
    if (parsed && (fields >> has_encoders >> left_ticks >> right_ticks >> has_velocities >> vx) &&
        has_velocities == 1.0) {
      pose.speed_mps = std::abs(vx);
    }
    if (!parsed || !std::isfinite(pose.t_s + pose.x_m + pose.y_m + pose.yaw_rad) ||
        (!reference.poses.empty() && pose.t_s <= reference.poses.back().t_s)) {
      ++reference.skipped_rows;
      continue;
    }
    if (!reference.poses.empty()) {
      // Unwrap: the heading turns by far less than pi between rows.
      const double previous = reference.poses.back().yaw_rad;
      pose.yaw_rad = previous + wrap_angle(pose.yaw_rad - previous);
    }
    reference.poses.push_back(pose);
  }
  if (reference.poses.size() < 2) {
    throw std::runtime_error(path + ": fewer than two poses (time x y phi per line)");
  }
  retime_by_speed(reference.poses);
  return reference;
}

// The robot's true state at t: the reference, with each wheel's travel from the path length
// and the turn (a differential base of the robot's track).
class TrueMotion {
 public:
  TrueMotion(const Reference& reference, double track_m)
      : reference_(reference), track_m_(track_m), last_(reference.poses.front()) {}

  hal::sim::RobotState step_to(double t_s) {
    const ReferencePose now = reference_.at(t_s);
    const double dt = t_s - last_.t_s;
    // Signed travel: the displacement along the heading (the vehicle may back up).
    const double ds = (now.x_m - last_.x_m) * std::cos(last_.yaw_rad) +
                      (now.y_m - last_.y_m) * std::sin(last_.yaw_rad);
    const double dyaw = now.yaw_rad - last_.yaw_rad;
    left_m_ += ds - 0.5 * track_m_ * dyaw;
    right_m_ += ds + 0.5 * track_m_ * dyaw;
    hal::sim::RobotState state;
    state.t_s = t_s;
    state.position_m = Eigen::Vector3d(now.x_m, now.y_m, 0.0);
    state.yaw_rad = wrap_angle(now.yaw_rad);
    const double speed = dt > 0.0 ? ds / dt : 0.0;
    state.accel_mps2 = dt > 0.0 ? (speed - speed_mps_) / dt : 0.0;
    state.speed_mps = speed;
    state.yaw_rate_radps = dt > 0.0 ? dyaw / dt : 0.0;
    state.left_wheel_m = left_m_;
    state.right_wheel_m = right_m_;
    speed_mps_ = speed;
    last_ = now;
    return state;
  }

 private:
  const Reference& reference_;
  double track_m_;
  ReferencePose last_;
  double left_m_ = 0.0;
  double right_m_ = 0.0;
  double speed_mps_ = 0.0;
};

std::FILE* open_or_throw(const fs::path& path) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) {
    throw std::runtime_error(path.string() + ": cannot be written");
  }
  return file;
}

struct Files {
  explicit Files(const fs::path& folder)
      : can(open_or_throw(folder / "rmp.candump")),
        gps(open_or_throw(folder / "gps.nmea")),
        truth_gps(open_or_throw(folder / "truth_gps.csv")) {}
  Files(const Files&) = delete;
  Files& operator=(const Files&) = delete;
  ~Files() {
    for (std::FILE* f : {can, gps, truth_gps}) {
      static_cast<void>(std::fclose(f));
    }
  }
  std::FILE* can;
  std::FILE* gps;
  std::FILE* truth_gps;
};

void write_status_group(std::FILE* out, const rmp::StatusFrames& frames, TimestampNs cycle_ns) {
  for (std::size_t k = 0; k < 8; ++k) {
    hal::protocol::candump::Record record;
    record.stamp_ns = cycle_ns + static_cast<TimestampNs>(k) * kFrameGapNs;
    std::snprintf(record.interface.data(), record.interface.size(), "can0");
    record.frame = frames.frames[k];
    std::array<char, 80> line{};
    const std::size_t length = hal::protocol::candump::format_line(record, line);
    line[length] = '\n';
    static_cast<void>(std::fwrite(line.data(), 1, length + 1, out));
  }
}

struct ScanImport {
  std::uint64_t scans = 0;
  std::uint64_t rows_outside = 0;  // before the first or after the last reference pose
};

// One B0 telegram per scan row, in a byte log record stamped with the row's time. A row whose
// range count is not the laser's is an error that names the line: a different laser setup.
ScanImport write_scans(const std::string& path, const hal::config::LaserSpec& laser,
                       const fs::path& folder, double start_s, double end_s) {
  namespace lms = hal::protocol::sick_lms2xx;
  namespace byte_log = hal::protocol::byte_log;
  std::ifstream file(path);
  if (!file) {
    throw std::runtime_error(path + ": cannot be read");
  }
  const std::size_t beams = lms::geometry(laser.variant).value_count;
  const fs::path log_path = folder / ("laser_" + laser.name + ".bytelog");
  std::FILE* out = open_or_throw(log_path);
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> closer(out, &std::fclose);
  // Every write is checked, and the close too (buffered bytes reach the disk there): a log
  // cut short by a full disk is an error, not a shorter run.
  const auto write = [&](const void* bytes, std::size_t size) {
    if (std::fwrite(bytes, 1, size, out) != size) {
      throw std::runtime_error(log_path.string() + ": cannot be written");
    }
  };
  write(byte_log::kMagic.data(), byte_log::kMagic.size());
  std::vector<double> fields;
  std::vector<std::uint16_t> values(beams);
  std::array<std::uint8_t, lms::kMaxTelegramBytes> telegram{};
  std::array<std::uint8_t, byte_log::kRecordHeaderBytes> header{};
  ScanImport result;
  std::size_t line_number = 0;
  for (std::string line; std::getline(file, line);) {
    ++line_number;
    if (line.empty() || line.front() == '%' || line.front() == '#') {
      continue;
    }
    fields.clear();
    std::istringstream row(line);
    for (double value = 0.0; row >> value;) {
      fields.push_back(value);
    }
    if (fields.size() != 1 + 2 * beams) {
      throw std::runtime_error(path + ":" + std::to_string(line_number) + ": " +
                               std::to_string(fields.size()) + " numbers, expected time, " +
                               std::to_string(beams) + " ranges and " + std::to_string(beams) +
                               " valid flags (the laser of the robot)");
    }
    const double t_s = fields[0];
    if (t_s < start_s || t_s > end_s) {
      ++result.rows_outside;
      continue;
    }
    for (std::size_t i = 0; i < beams; ++i) {
      const bool valid = fields[1 + beams + i] != 0.0;
      values[i] = lms::encode_beam(fields[1 + i],
                                   valid ? msg::BeamStatus::kValid : msg::BeamStatus::kNoReturn,
                                   laser.units, laser.range_bits);
    }
    const std::size_t length = lms::encode_measured_values(telegram, values, laser.units, 0);
    const byte_log::RecordHeader record{static_cast<TimestampNs>(std::llround(t_s * 1e9)),
                                        static_cast<std::uint32_t>(length),
                                        byte_log::Direction::kFromDevice};
    byte_log::encode_record_header(record, header);
    write(header.data(), header.size());
    write(telegram.data(), length);
    ++result.scans;
  }
  if (std::fclose(closer.release()) != 0) {
    throw std::runtime_error(log_path.string() + ": cannot be written");
  }
  return result;
}

// GGA and RMC of one epoch, as the simulated receiver sends them (open sky: the spec's HDOP).
void write_epoch(std::FILE* out, const hal::config::GpsSpec& spec, double utc_s,
                 const hal::GeodeticPoint& point) {
  msg::GpsFix fix;
  hal::sim::set_fix_utc(fix, utc_s);
  fix.valid = true;
  fix.has_quality = true;
  fix.quality = msg::GpsFixQuality::kGps;
  fix.has_satellites = true;
  fix.satellites_used = static_cast<std::uint8_t>(spec.satellites);
  fix.has_position = true;
  fix.latitude_deg = point.latitude_deg;
  fix.longitude_deg = point.longitude_deg;
  fix.has_altitude = true;
  fix.altitude_msl_m = point.height_m;  // geoid separation 0: the reference has no geoid
  fix.has_geoid_separation = true;
  fix.has_hdop = true;
  fix.hdop = spec.hdop_open_sky;
  std::array<char, nmea::kMaxSentenceBytes> sentence{};
  for (const auto encode : {&nmea::encode_gga, &nmea::encode_rmc}) {
    const std::size_t length = encode(fix, spec.talker, sentence);
    static_cast<void>(std::fwrite(sentence.data(), 1, length, out));
  }
}

Json truth_pose(const hal::sim::RobotState& state, double unix_s) {
  Json pose;
  pose["t_s"] = rounded(unix_s, 6);
  pose["x_m"] = rounded(state.position_m.x(), 4);
  pose["y_m"] = rounded(state.position_m.y(), 4);
  pose["z_m"] = 0.0;
  pose["roll_rad"] = 0.0;
  pose["pitch_rad"] = 0.0;
  pose["yaw_rad"] = rounded(state.yaw_rad, 6);
  pose["speed_mps"] = rounded(state.speed_mps, 4);
  return pose;
}

int import_trajectory(const ImportOptions& options, std::ostream& err) {
  const std::optional<hal::GeodeticPoint> parsed_origin = parse_origin(options.origin);
  if (!parsed_origin) {
    err << "blockmap: import: " << kOriginFormatError << '\n';
    return kExitUsage;
  }
  const hal::GeodeticPoint origin = *parsed_origin;
  const Reference reference = read_reference(options.trajectory);
  std::string robot_source;
  const std::string robot_toml = hal::config::robot_text(options.robot, robot_source);
  const hal::config::RobotSpec robot = hal::config::parse_robot(robot_toml, robot_source);
  const fs::path folder(options.out);
  fs::create_directories(folder);
  std::ofstream(folder / "robot.toml") << robot_toml;
  Files files(folder);
  std::fprintf(files.truth_gps,
               "t_s,x_m,y_m,z_m,error_e_m,error_n_m,error_u_m,satellites,hdop,fix\n");

  const hal::LocalEnuFrame frame(origin);
  Random base_random(options.seed, "rmp");
  Random gps_random(options.seed, "gps");
  hal::sim::BaseSensing sensing(robot.base);
  hal::sim::GpsErrorProcess gps_error(robot.gps);
  gps_error.start(gps_random);
  TrueMotion motion(reference, robot.base.track_m);
  rmp::Config codec;
  codec.model = robot.base.model;
  codec.yaw_sign = robot.base.yaw_sign;

  const double start_s = reference.poses.front().t_s;
  const double end_s = reference.poses.back().t_s;
  const double gps_period_s = 1.0 / robot.gps.rate_hz;
  double next_epoch_s = start_s + gps_period_s;
  Json trajectory = Json::array();
  std::uint64_t cycles = 0;
  std::uint64_t epochs = 0;
  for (std::uint64_t cycle = 1;; ++cycle) {
    const double t = start_s + static_cast<double>(cycle) * kCycleS;
    if (t > end_s) {
      break;
    }
    ++cycles;
    const hal::sim::RobotState state = motion.step_to(t);
    trajectory.push_back(truth_pose(state, t));
    const auto cycle_ns = static_cast<TimestampNs>(std::llround(t * 1e9));
    write_status_group(files.can,
                       rmp::encode_status(sensing.sense(state, kCycleS, cycle, base_random), codec),
                       cycle_ns);
    while (next_epoch_s <= t) {
      gps_error.advance(gps_period_s, gps_random);
      // The antenna on the robot, at the state of this cycle (within 10 ms of the epoch).
      const Eigen::Vector3d antenna = state.position_m + state.rotation() * robot.gps.antenna_m;
      const Eigen::Vector3d error = gps_error.error_m();
      write_epoch(files.gps, robot.gps, next_epoch_s, frame.to_geodetic(antenna + error));
      std::fprintf(files.truth_gps, "%.6f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%d,%.2f,1\n", next_epoch_s,
                   antenna.x(), antenna.y(), antenna.z(), error.x(), error.y(), error.z(),
                   robot.gps.satellites, robot.gps.hdop_open_sky);
      next_epoch_s += gps_period_s;
      ++epochs;
    }
  }
  Json truth;
  truth["source"] = options.trajectory;
  truth["robot"] = robot.name;
  truth["seed"] = options.seed;
  truth["start_unix_s"] = rounded(start_s, 6);
  truth["origin"] = {{"latitude_deg", origin.latitude_deg},
                     {"longitude_deg", origin.longitude_deg},
                     {"height_m", origin.height_m}};
  truth["trajectory"] = std::move(trajectory);
  truth["faces"] = Json::array();
  truth["buildings"] = Json::array();
  std::ofstream(folder / "truth.json") << truth.dump() << '\n';
  if (!options.scans.empty()) {
    if (robot.lasers.empty()) {
      throw hal::ConfigError("--scans: robot " + robot.name + " has no laser to carry them");
    }
    const ScanImport scans =
        write_scans(options.scans, robot.lasers.front(), folder, start_s, end_s);
    err << "import: " << scans.scans << " scans -> laser_" << robot.lasers.front().name
        << ".bytelog (" << scans.rows_outside << " outside the trajectory's time)\n";
  }
  err << "import: " << reference.poses.size() << " reference poses (" << reference.skipped_rows
      << " rows skipped), " << (end_s - start_s) << " s; " << cycles << " RMP cycles, " << epochs
      << " GPS epochs -> " << options.out << '\n';
  return kExitOk;
}

}  // namespace

Command add_import_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "import",
      "Make a robot's device logs (RMP CAN, NMEA) from a real vehicle's reference trajectory, "
      "with the robot's sensor errors, for blockmap replay");
  auto options = std::make_shared<ImportOptions>();
  command
      ->add_option("TRAJECTORY", options->trajectory,
                   "an MRPT odometry text export: time x y phi ... per line")
      ->required();
  command->add_option("--out", options->out, "the folder to write the logs into")->required();
  command
      ->add_option("--origin", options->origin,
                   "where the trajectory's frame is on Earth: LAT,LON,HEIGHT")
      ->required();
  command->add_option("--scans", options->scans,
                      "an MRPT 2D-scan text export (time, ranges, valid flags per line): the "
                      "robot's first laser's telegrams");
  command
      ->add_option("--robot", options->robot,
                   "a built-in robot (paper_rmp, ual_car) or a robot .toml")
      ->capture_default_str();
  command->add_option("--seed", options->seed, "the sensor errors' seed")->capture_default_str();
  return {command, [options](std::ostream& /*out*/, std::ostream& err) {
            try {
              return import_trajectory(*options, err);
            } catch (const hal::ConfigError& error) {
              err << "blockmap: import: " << error.what() << '\n';
              return kExitUsage;
            } catch (const std::runtime_error& error) {
              err << "blockmap: import: " << error.what() << '\n';
              return kExitFailure;
            }
          }};
}

}  // namespace blockmap::cli
