// Robot files (config/robots/*.toml) -> RobotSpec. The keys are listed in config/README.md.
#include "blockmap/core/angles.hpp"
#include "blockmap/hal/config/robot.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

#include "blockmap/localize/localizer.hpp"
#include "builtin_robots.hpp"
#include "toml_reader.hpp"

namespace blockmap::hal::config {
namespace {

namespace lms = protocol::sick_lms2xx;

double degrees_or(TableReader& table, std::string_view key, double fallback_rad) {
  return table.number_or(key, fallback_rad / kRadiansPerDegree) * kRadiansPerDegree;
}

map::SensorMount parse_mount(TableReader& table) {
  map::SensorMount mount;
  mount.position_m = table.vec3("position_m");
  mount.roll_rad = degrees_or(table, "roll_deg", 0.0);
  mount.pitch_rad = degrees_or(table, "pitch_deg", 0.0);
  mount.yaw_rad = degrees_or(table, "yaw_deg", 0.0);
  return mount;
}

BaseSpec parse_base(TableReader& root) {
  BaseSpec base;
  std::optional<TableReader> table = root.table("base");
  if (!table) {
    return base;
  }
  const std::string model = table->string_or("model", "rmp200");
  if (model == "rmp50") {
    base.model = protocol::segway_rmp::Model::kRmp50;
  } else if (model == "rmp100") {
    base.model = protocol::segway_rmp::Model::kRmp100;
  } else if (model == "rmp200") {
    base.model = protocol::segway_rmp::Model::kRmp200;
  } else if (model == "rmp400") {
    base.model = protocol::segway_rmp::Model::kRmp400;
  } else {
    table->fail("model", "expected rmp50, rmp100, rmp200 or rmp400");
  }
  base.yaw_sign = static_cast<int>(table->integer_or("yaw_sign", 1));
  if (base.yaw_sign != 1 && base.yaw_sign != -1) {
    table->fail("yaw_sign", "must be 1 or -1");
  }
  TableReader& t = *table;
  base.track_m = t.in_range("track_m", t.number_or("track_m", base.track_m), 0.1, 3.0);
  base.wheel_radius_m =
      t.in_range("wheel_radius_m", t.number_or("wheel_radius_m", base.wheel_radius_m), 0.05, 1.0);
  base.max_accel_mps2 = t.positive_or("max_accel_mps2", base.max_accel_mps2);
  base.max_decel_mps2 = t.positive_or("max_decel_mps2", base.max_decel_mps2);
  base.max_lateral_accel_mps2 =
      t.positive_or("max_lateral_accel_mps2", base.max_lateral_accel_mps2);
  base.max_yaw_rate_radps = t.positive(
      "max_yaw_rate_degps", degrees_or(t, "max_yaw_rate_degps", base.max_yaw_rate_radps));
  base.lookahead_m =
      t.in_range("lookahead_m", t.number_or("lookahead_m", base.lookahead_m), 0.2, 20.0);
  base.pitch_per_accel_rad_per_mps2 =
      degrees_or(t, "pitch_per_accel_deg_per_mps2", base.pitch_per_accel_rad_per_mps2);
  base.pitch_natural_frequency_hz = t.in_range(
      "pitch_natural_frequency_hz",
      t.number_or("pitch_natural_frequency_hz", base.pitch_natural_frequency_hz), 0.1, 20.0);
  base.pitch_damping_ratio =
      t.in_range("pitch_damping_ratio",
                 t.number_or("pitch_damping_ratio", base.pitch_damping_ratio), 0.05, 5.0);
  base.bump_pitch_gain = t.non_negative_or("bump_pitch_gain", base.bump_pitch_gain);
  base.left_scale_error = t.in_range(
      "left_scale_error", t.number_or("left_scale_error", base.left_scale_error), -0.2, 0.2);
  base.right_scale_error = t.in_range(
      "right_scale_error", t.number_or("right_scale_error", base.right_scale_error), -0.2, 0.2);
  base.slip_fraction =
      t.in_range("slip_fraction", t.number_or("slip_fraction", base.slip_fraction), 0.0, 0.5);
  base.yaw_rate_bias_radps = degrees_or(t, "yaw_rate_bias_degps", base.yaw_rate_bias_radps);
  base.yaw_rate_noise_radps = t.non_negative(
      "yaw_rate_noise_degps", degrees_or(t, "yaw_rate_noise_degps", base.yaw_rate_noise_radps));
  base.pitch_noise_rad =
      t.non_negative("pitch_noise_deg", degrees_or(t, "pitch_noise_deg", base.pitch_noise_rad));
  base.roll_noise_rad =
      t.non_negative("roll_noise_deg", degrees_or(t, "roll_noise_deg", base.roll_noise_rad));
  base.rate_noise_radps =
      t.non_negative("rate_noise_degps", degrees_or(t, "rate_noise_degps", base.rate_noise_radps));
  t.finish();
  return base;
}

lms::AngularVariant parse_variant(TableReader& table) {
  const double field = table.number_or("field_deg", 180.0);
  const double resolution = table.number_or("resolution_deg", 1.0);
  if (field == 180.0 && resolution == 1.0) {
    return lms::AngularVariant::k180Deg1Deg;
  }
  if (field == 180.0 && resolution == 0.5) {
    return lms::AngularVariant::k180DegHalfDeg;
  }
  if (field == 100.0 && resolution == 1.0) {
    return lms::AngularVariant::k100Deg1Deg;
  }
  if (field == 100.0 && resolution == 0.5) {
    return lms::AngularVariant::k100DegHalfDeg;
  }
  if (field == 100.0 && resolution == 0.25) {
    return lms::AngularVariant::k100DegQuarterDeg;
  }
  table.fail("resolution_deg",
             "the LMS2xx scans 180 deg at 1 or 0.5 deg, or 100 deg at 1, 0.5 "
             "or 0.25 deg (field_deg, resolution_deg)");
}

LaserSpec parse_laser(TableReader& table) {
  LaserSpec laser;
  laser.name = table.string("name");
  if (laser.name.empty() ||
      laser.name.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_") != std::string::npos) {
    table.fail("name", "use lower-case letters, digits and '_' (it names the log file)");
  }
  const std::string protocol = table.string_or("protocol", "lms2xx");
  if (protocol == "tim") {
    // A TiM over USB: its mount, and its rate for the record (15 Hz for the TiM5xx); its
    // telegrams say the rest.
    laser.protocol = LaserProtocol::kTim;
    laser.mount = parse_mount(table);
    laser.scan_rate_hz =
        table.in_range("scan_rate_hz", table.number_or("scan_rate_hz", 15.0), 1.0, 100.0);
    table.finish();
    return laser;
  }
  if (protocol != "lms2xx") {
    table.fail(
        "protocol",
        R"(expected "lms2xx" (a SICK LMS2xx on a serial line) or "tim" (a SICK TiM over USB))");
  }
  laser.mount = parse_mount(table);
  laser.variant = parse_variant(table);
  const double max_rate = kLms2xxMirrorRateHz / mirror_turns_per_scan(laser.variant);
  laser.scan_rate_hz = table.number_or("scan_rate_hz", max_rate);
  const double skip = max_rate / laser.scan_rate_hz;
  if (!(laser.scan_rate_hz > 0.0) || laser.scan_rate_hz > max_rate * 1.0001 ||
      std::abs(skip - std::round(skip)) > 1e-3) {
    std::ostringstream what;
    what << "must be " << max_rate << " Hz divided by a whole number (the mirror turns at 75 Hz)";
    table.fail("scan_rate_hz", what.str());
  }
  const std::string units = table.string_or("units", "cm");
  if (units == "cm") {
    laser.units = lms::Units::kCm;
  } else if (units == "mm") {
    laser.units = lms::Units::kMm;
  } else {
    table.fail("units", R"(expected "cm" or "mm")");
  }
  const std::int64_t range_bits = table.integer_or("range_bits", 13);
  if (range_bits < 13 || range_bits > 15) {
    table.fail("range_bits", "must be 13, 14 or 15");
  }
  laser.range_bits = static_cast<std::uint8_t>(range_bits);
  const std::int64_t baud = table.integer_or("baud", 500000);
  if (baud != 9600 && baud != 19200 && baud != 38400 && baud != 500000) {
    table.fail("baud", "the LMS2xx runs at 9600, 19200, 38400 or 500000 Bd");
  }
  laser.baud = static_cast<std::uint32_t>(baud);
  // A telegram must be on the wire before the next scan is due.
  const double telegram_bytes = 10.0 + 2.0 * lms::geometry(laser.variant).value_count;
  const double wire_s = telegram_bytes * 10.0 / static_cast<double>(laser.baud);
  if (wire_s > 1.0 / laser.scan_rate_hz) {
    std::ostringstream what;
    what << "at " << laser.baud << " Bd a scan takes " << std::lround(wire_s * 1000.0)
         << " ms to send, longer than the scan period of "
         << std::lround(1000.0 / laser.scan_rate_hz) << " ms: lower scan_rate_hz or raise baud";
    table.fail("scan_rate_hz", what.str());
  }
  laser.range_noise_m = table.in_range(
      "range_noise_m", table.number_or("range_noise_m", laser.range_noise_m), 0.0, 1.0);
  laser.missing_return_probability = table.in_range(
      "missing_return_probability",
      table.number_or("missing_return_probability", laser.missing_return_probability), 0.0, 1.0);
  laser.read_interval_s = table.in_range(
      "read_interval_s", table.number_or("read_interval_s", laser.read_interval_s), 1e-4, 0.1);
  table.finish();
  return laser;
}

GpsSpec parse_gps(TableReader& root) {
  GpsSpec gps;
  std::optional<TableReader> table = root.table("gps");
  if (!table) {
    return gps;
  }
  TableReader& t = *table;
  if (t.has("antenna_m")) {
    gps.antenna_m = t.vec3("antenna_m");
  }
  gps.rate_hz = t.in_range("rate_hz", t.number_or("rate_hz", gps.rate_hz), 0.1, 20.0);
  const std::int64_t baud = t.integer_or("baud", gps.baud);
  if (baud != 4800 && baud != 9600 && baud != 19200 && baud != 38400 && baud != 57600 &&
      baud != 115200) {
    t.fail("baud", "expected 4800, 9600, 19200, 38400, 57600 or 115200");
  }
  gps.baud = static_cast<std::uint32_t>(baud);
  // GGA, RMC and GSA: about 220 bytes an epoch.
  if (220.0 * 10.0 * gps.rate_hz > static_cast<double>(gps.baud)) {
    t.fail("rate_hz", "GGA, RMC and GSA at this rate do not fit the baud rate");
  }
  gps.talker = t.string_or("talker", gps.talker);
  if (gps.talker.size() != 2) {
    t.fail("talker", "must be two characters (GP, GN, ...)");
  }
  gps.horizontal_error_rms_m =
      t.non_negative_or("horizontal_error_rms_m", gps.horizontal_error_rms_m);
  gps.multipath_error_rms_m = t.non_negative_or("multipath_error_rms_m", gps.multipath_error_rms_m);
  if (gps.multipath_error_rms_m > gps.horizontal_error_rms_m) {
    t.fail("multipath_error_rms_m", "is part of horizontal_error_rms_m: it cannot exceed it");
  }
  gps.vertical_error_rms_m = t.non_negative_or("vertical_error_rms_m", gps.vertical_error_rms_m);
  gps.correlation_time_s = t.positive_or("correlation_time_s", gps.correlation_time_s);
  gps.multipath_correlation_s =
      t.positive_or("multipath_correlation_s", gps.multipath_correlation_s);
  gps.latency_s = t.in_range("latency_s", t.number_or("latency_s", gps.latency_s), 0.0, 1.0);
  gps.hdop_open_sky =
      t.in_range("hdop_open_sky", t.number_or("hdop_open_sky", gps.hdop_open_sky), 0.5, 20.0);
  const std::string quality = t.string_or("fix_quality", "gps");
  if (quality == "gps") {
    gps.fix_quality = msg::GpsFixQuality::kGps;
  } else if (quality == "dgps") {
    gps.fix_quality = msg::GpsFixQuality::kDgps;
  } else if (quality == "rtk_float") {
    gps.fix_quality = msg::GpsFixQuality::kRtkFloat;
  } else if (quality == "rtk_fixed") {
    gps.fix_quality = msg::GpsFixQuality::kRtkFixed;
  } else {
    t.fail("fix_quality", "expected gps, dgps, rtk_float or rtk_fixed");
  }
  gps.satellites = static_cast<int>(t.integer_or("satellites", gps.satellites));
  if (gps.satellites < 4 || gps.satellites > 12) {
    t.fail("satellites", "must lie in [4, 12]");
  }
  gps.elevation_mask_deg = t.in_range(
      "elevation_mask_deg", t.number_or("elevation_mask_deg", gps.elevation_mask_deg), 0.0, 45.0);
  gps.read_interval_s =
      t.in_range("read_interval_s", t.number_or("read_interval_s", gps.read_interval_s), 1e-4, 1.0);
  t.finish();
  return gps;
}

}  // namespace

int mirror_turns_per_scan(lms::AngularVariant variant) noexcept {
  switch (lms::geometry(variant).resolution_centideg) {
    case 50:
      return 2;
    case 25:
      return 4;
    default:
      return 1;
  }
}

RobotSpec parse_robot(std::string_view toml_text, std::string_view source_name) {
  const toml::table document = parse_document(toml_text, source_name);
  TableReader root(document, std::string(source_name), "");
  RobotSpec robot;
  robot.name = root.string("name");
  robot.base = parse_base(root);
  for (TableReader& table : root.tables("lasers")) {
    robot.lasers.push_back(parse_laser(table));
    for (std::size_t i = 0; i + 1 < robot.lasers.size(); ++i) {
      if (robot.lasers[i].name == robot.lasers.back().name) {
        table.fail("name", "\"" + robot.lasers.back().name + "\" is used twice");
      }
    }
  }
  if (robot.lasers.size() > 4) {
    root.fail("lasers", "at most 4 lasers");
  }
  robot.gps = parse_gps(root);
  root.finish();
  return robot;
}

std::string robot_text(std::string_view name_or_path, std::string& source) {
  return builtin_or_file_text(kBuiltinRobotNames, kBuiltinRobotTexts, name_or_path, "robot",
                              source);
}

void require_lms2xx_lasers(const RobotSpec& robot, std::string_view user) {
  for (const LaserSpec& laser : robot.lasers) {
    if (laser.protocol != LaserProtocol::kLms2xx) {
      throw ConfigError("robot " + robot.name + ": laser " + laser.name +
                        " is a SICK TiM (protocol = \"tim\"): " + std::string(user) +
                        " has SICK LMS2xx lasers only");
    }
  }
}

RobotSpec load_robot(std::string_view name_or_path) {
  std::string source;
  const std::string text = robot_text(name_or_path, source);
  return parse_robot(text, source);
}

}  // namespace blockmap::hal::config
