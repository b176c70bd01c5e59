// A robot's description: a Segway RMP with its lasers and GPS receiver, as a robot file
// describes it (config/robots/*.toml; keys in config/README.md), for the daemon on the robot,
// the replay of its logs and the simulator alike. The built-in `paper_rmp` is the paper's
// robot: an RMP 200, two SICK LMS291 (one horizontal, one vertical pushbroom) and a 2 m GPS.
// The error models (a base's slip, a receiver's error budget) are what the simulator makes
// of a robot of this kind; the rest is the robot.
//
// Robot frame: origin at the middle of the wheel axle, x forward, y left, z up; the chassis
// pitches about the axle (positive pitch: nose down, leaning forward) and rolls with the ground
// under the two wheels. A sensor's mount is its pose in this frame (roll, then pitch, then yaw).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "blockmap/map/scan_projector.hpp"
#include "blockmap/msg/gps_fix.hpp"
#include "blockmap/pipeline/mapper_config.hpp"

namespace blockmap::hal::config {

struct BaseSpec {
  protocol::segway_rmp::Model model = protocol::segway_rmp::Model::kRmp200;
  int yaw_sign = 1;  // as the device layer will be configured (docs/protocols.md 1.8)
  double track_m = 0.54;
  double wheel_radius_m = 0.24;
  // Driving: how the base follows the path.
  double max_accel_mps2 = 0.5;
  double max_decel_mps2 = 0.7;
  double max_lateral_accel_mps2 = 0.4;
  double max_yaw_rate_radps = 0.8;
  double lookahead_m = 1.5;
  // Pitch: a damped second-order response to the forward acceleration (the RMP leans into it)
  // and to the slope of the ground under the wheels (bumps jolt it).
  double pitch_per_accel_rad_per_mps2 = 0.07;  // 4 deg per m/s^2
  double pitch_natural_frequency_hz = 1.2;
  double pitch_damping_ratio = 0.55;
  double bump_pitch_gain = 0.6;  // rad of pitch demand per rad of ground slope
  // What the base reports, and how wrong it is.
  double left_scale_error = 0.012;  // tyre pressure: reported distance = true * (1 + error)
  double right_scale_error = -0.006;
  double slip_fraction = 0.01;  // random slip, a fraction of each wheel increment
  double yaw_rate_bias_radps = 0.005;
  double yaw_rate_noise_radps = 0.01;
  double pitch_noise_rad = 0.003;
  double roll_noise_rad = 0.003;
  double rate_noise_radps = 0.01;
};

// The LMS2xx's mirror turns at 75 Hz; a scan at 0.5 deg interlaces two turns, at 0.25 deg four
// (docs/protocols.md 2.1).
inline constexpr double kLms2xxMirrorRateHz = 75.0;
[[nodiscard]] int mirror_turns_per_scan(protocol::sick_lms2xx::AngularVariant variant) noexcept;

// What a laser speaks: an LMS2xx on a serial line (the paper's, and the simulator's), or a
// TiM over USB (the modern variant: the daemon only; its telegrams carry their own geometry).
enum class LaserProtocol : std::uint8_t { kLms2xx, kTim };

struct LaserSpec {
  std::string name;  // log file laser_<name>.bytelog
  LaserProtocol protocol = LaserProtocol::kLms2xx;
  map::SensorMount mount;
  protocol::sick_lms2xx::AngularVariant variant =
      protocol::sick_lms2xx::AngularVariant::k180Deg1Deg;
  double scan_rate_hz = 75.0;  // the mirror turns at 75 Hz; 0.5 deg needs two turns per scan
  protocol::sick_lms2xx::Units units = protocol::sick_lms2xx::Units::kCm;
  std::uint8_t range_bits = 13;  // 13 bits in cm: 81.91 m
  std::uint32_t baud = 500000;
  double range_noise_m = 0.01;
  double missing_return_probability = 0.002;
  double read_interval_s = 0.002;  // the host's reads return this often
};

struct GpsSpec {
  Eigen::Vector3d antenna_m = Eigen::Vector3d(0.0, 0.0, 1.2);
  double rate_hz = 4.0;
  std::uint32_t baud = 9600;
  std::string talker = "GP";
  // The receiver's error budget in two parts. A slow part (satellite orbits and clocks, the
  // atmosphere) wanders with correlation_time_s. A fast part (multipath and receiver noise,
  // which change within seconds as the robot moves between buildings) wanders with
  // multipath_correlation_s. horizontal_error_rms_m is the RMS of the sum; the vertical error
  // is slow only.
  double horizontal_error_rms_m = 2.0;
  double multipath_error_rms_m = 1.6;
  double vertical_error_rms_m = 3.0;
  double correlation_time_s = 60.0;
  double multipath_correlation_s = 2.0;
  double latency_s = 0.05;  // from the epoch to the first byte of its sentences
  double hdop_open_sky = 0.9;
  // What GGA says the fixes were corrected with: a code receiver's kGps, or a carrier-phase
  // (RTK) receiver's kRtkFixed, whose error budget above is then centimetres.
  msg::GpsFixQuality fix_quality = msg::GpsFixQuality::kGps;
  int satellites = 10;  // the constellation above the site
  double elevation_mask_deg = 10.0;
  double read_interval_s = 0.01;
};

struct RobotSpec {
  std::string name;
  BaseSpec base;
  std::vector<LaserSpec> lasers;
  GpsSpec gps;
};

// A robot file's text -> RobotSpec. Mistakes throw ConfigError naming the file and the key.
[[nodiscard]] RobotSpec parse_robot(std::string_view toml_text, std::string_view source_name);
// The text of the built-in `paper_rmp` (by name) or of a robot file (by path); `source` is set
// to the name errors carry. Throws ConfigError.
[[nodiscard]] std::string robot_text(std::string_view name_or_path, std::string& source);
// robot_text() parsed. Throws ConfigError.
[[nodiscard]] RobotSpec load_robot(std::string_view name_or_path);

// Throws ConfigError naming the first laser of `robot` that is not an LMS2xx: `user` (the
// simulator, the replay of byte logs) has LMS2xx lasers only.
void require_lms2xx_lasers(const RobotSpec& robot, std::string_view user);

// The device layer's configuration for the robot's base: its RMP model and yaw sign.
[[nodiscard]] devices::SegwayBaseConfig segway_base_config_for(const RobotSpec& robot);

// The device layer's configuration for one of the robot's LMS2xx lasers: its codec settings
// and, when one mirror turn makes a scan, its timing.
[[nodiscard]] devices::Lms2xxScannerConfig lms2xx_config_for(const LaserSpec& spec);

// The mapper's configuration for a robot: its lasers' mounts (the first kMaxLasers) and its
// GPS antenna's height; everything else at its defaults.
[[nodiscard]] pipeline::MapperConfig mapper_config_for(const RobotSpec& robot);

}  // namespace blockmap::hal::config
