// The simulated GPS receiver. Its error has a slow part (orbits, clocks, the atmosphere) and a
// fast one (multipath and receiver noise), each a first-order Gauss-Markov process per axis
// with its own RMS and correlation time; together they make the paper's 2 m receiver. It
// sees a fixed constellation; a building between the antenna and a satellite hides it, fewer
// satellites raise the HDOP and the error with it, and with fewer than four there is no fix
// (the paper: "unavailable due to satellite occlusions by tall buildings"). Each epoch's GGA, RMC
// and GSA go out on the serial line a little after the epoch.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include "blockmap/core/angles.hpp"
#include "sim_devices.hpp"

namespace blockmap::hal::sim::detail {
namespace {

namespace nmea = protocol::nmea;

// Distance along the 2D ray p + t * direction to the first crossing of the polygon's boundary.
double first_crossing(const std::vector<Vec2>& polygon, const Vec2& p, const Vec2& direction) {
  double best = std::numeric_limits<double>::max();
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Vec2& a = polygon[i];
    const Vec2 edge = polygon[(i + 1) % polygon.size()] - a;
    const double denominator = direction.x() * edge.y() - direction.y() * edge.x();
    if (std::abs(denominator) < 1e-12) {
      continue;
    }
    const Vec2 ap = a - p;
    const double t = (ap.x() * edge.y() - ap.y() * edge.x()) / denominator;
    const double u = (ap.x() * direction.y() - ap.y() * direction.x()) / denominator;
    if (t > 0.0 && u >= 0.0 && u <= 1.0) {
      best = std::min(best, t);
    }
  }
  return best;
}

}  // namespace

SimGps::SimGps(const config::GpsSpec& spec, const Site& site, std::size_t device,
               std::uint64_t seed)
    : spec_(spec),
      site_(site),
      frame_(site.origin),
      device_(device),
      random_(seed, "gps"),
      jumps_random_(seed, "gps.jumps"),
      wire_(spec.baud, static_cast<TimestampNs>(spec.read_interval_s * 1e9), 2048),
      error_(spec) {
  // The constellation: uniform in azimuth, uniform in the sine of the elevation above the mask.
  const double mask = spec.elevation_mask_deg * kRadiansPerDegree;
  for (int i = 0; i < spec.satellites; ++i) {
    Satellite satellite;
    satellite.azimuth_rad = random_.uniform(0.0, 2.0 * std::numbers::pi);
    satellite.elevation_rad = std::asin(random_.uniform(std::sin(mask + 0.05), 1.0));
    satellite.id = static_cast<std::uint16_t>(2 + 3 * i);
    satellites_.push_back(satellite);
  }
  error_.start(random_);
}

TimestampNs SimGps::epoch_ns(const SimContext& context, std::uint64_t epoch) const {
  return context.stamp(static_cast<double>(epoch) / spec_.rate_hz);
}

TimestampNs SimGps::next_event_ns(const SimContext& context) const noexcept {
  TimestampNs next = wire_.next_read_ns();
  const TimestampNs epoch = epoch_ns(context, next_epoch_);
  if (epoch <= context.end_ns) {
    next = std::min(next, epoch);
  }
  return next;
}

void SimGps::fire(SimContext& context, SimSink& sink, SimStats& stats) {
  const TimestampNs epoch = epoch_ns(context, next_epoch_);
  if (epoch <= wire_.next_read_ns() && epoch <= context.end_ns) {
    make_epoch(context, sink, stats);
    ++next_epoch_;
    return;
  }
  TimestampNs stamp_ns = 0;
  const std::span<const std::uint8_t> bytes = wire_.read(stamp_ns);
  sink.on_serial(device_, stamp_ns, protocol::byte_log::Direction::kFromDevice, bytes);
}

bool SimGps::blocked(const SimContext& context, const Vec3& antenna,
                     const Satellite& satellite) const {
  const Vec2 direction(std::sin(satellite.azimuth_rad), std::cos(satellite.azimuth_rad));
  for (const Building& building : context.scene.world().buildings) {
    const double distance = first_crossing(building.footprint_m, antenna.head<2>(), direction);
    if (distance == std::numeric_limits<double>::max()) {
      continue;
    }
    if (std::atan2(building.height_m - antenna.z(), distance) > satellite.elevation_rad) {
      return true;
    }
  }
  return false;
}

void SimGps::make_epoch(SimContext& context, SimSink& sink, SimStats& stats) {
  const TimestampNs epoch = epoch_ns(context, next_epoch_);
  const double t_s = context.seconds(epoch);
  context.motion.advance_to(t_s);
  const RobotState state = context.motion.state_at(t_s);
  GpsTruth truth;
  truth.epoch_ns = epoch;
  truth.antenna_m = state.position_m + state.rotation() * spec_.antenna_m;

  error_.advance(1.0 / spec_.rate_hz, random_);

  nmea::GsaData gsa;
  gsa.automatic = true;
  for (const Satellite& satellite : satellites_) {
    if (!blocked(context, truth.antenna_m, satellite) && gsa.satellite_count < 12) {
      gsa.satellite_ids[gsa.satellite_count++] = satellite.id;
    }
  }
  truth.satellites_visible = gsa.satellite_count;
  truth.fix = truth.satellites_visible >= 4;
  truth.hdop = truth.fix ? spec_.hdop_open_sky * std::sqrt(static_cast<double>(satellites_.size()) /
                                                           truth.satellites_visible)
                         : 99.9;
  // Fewer satellites, worse geometry: the error grows with the HDOP.
  truth.error_m = error_.error_m() * (truth.fix ? truth.hdop / spec_.hdop_open_sky : 1.0);
  if (jump_fraction_ > 0.0) {
    // Drawn for every epoch, so that which ones jump does not depend on the fixes.
    const bool jumps = jumps_random_.uniform(0.0, 1.0) < jump_fraction_;
    const double direction_rad = jumps_random_.uniform(0.0, 2.0 * std::numbers::pi);
    if (jumps && truth.fix) {
      truth.error_m.x() += jump_m_ * std::cos(direction_rad);
      truth.error_m.y() += jump_m_ * std::sin(direction_rad);
    }
  }

  msg::GpsFix fix;
  const double utc_s = site_.start_unix_s + t_s;
  set_fix_utc(fix, utc_s);
  fix.valid = truth.fix;
  fix.has_quality = true;
  fix.quality = truth.fix ? spec_.fix_quality : msg::GpsFixQuality::kInvalid;
  fix.has_satellites = true;
  fix.satellites_used = static_cast<std::uint8_t>(truth.fix ? truth.satellites_visible : 0);
  if (truth.fix) {
    const GeodeticPoint point = frame_.to_geodetic(truth.antenna_m + truth.error_m);
    fix.has_position = true;
    fix.latitude_deg = point.latitude_deg;
    fix.longitude_deg = point.longitude_deg;
    fix.has_altitude = true;
    fix.altitude_msl_m = point.height_m - site_.geoid_separation_m;
    fix.has_geoid_separation = true;
    fix.geoid_separation_m = site_.geoid_separation_m;
    fix.has_hdop = true;
    fix.hdop = truth.hdop;
    // Doppler speed and course: the true motion with a little noise.
    const double speed = std::max(0.0, state.speed_mps + random_.gaussian(0.05));
    fix.has_velocity = true;
    fix.speed_mps = speed;
    fix.has_course = speed > 0.2;
    double course = 90.0 - state.yaw_rad / kRadiansPerDegree + random_.gaussian(1.0);
    fix.course_deg = std::fmod(std::fmod(course, 360.0) + 360.0, 360.0);
  }
  gsa.fix_type = truth.fix ? 3 : 1;
  gsa.has_hdop = truth.fix;
  gsa.hdop = truth.hdop;
  gsa.has_pdop = truth.fix;
  gsa.pdop = truth.hdop * 1.6;
  gsa.has_vdop = truth.fix;
  gsa.vdop = truth.hdop * 1.3;
  sink.on_gps_epoch(truth);
  ++stats.gps_epochs;
  if (!truth.fix) {
    ++stats.gps_epochs_without_fix;
  }

  if (epoch >= silent_from_ns_ && epoch < silent_to_ns_) {
    ++stats.gps_epochs_silent;
    return;
  }
  const TimestampNs send_ns = epoch + static_cast<TimestampNs>(spec_.latency_s * 1e9);
  const auto send = [&](std::size_t length) {
    (void)wire_.send(std::span<const std::uint8_t>(
                         reinterpret_cast<const std::uint8_t*>(sentence_.data()), length),
                     send_ns);
  };
  send(nmea::encode_gga(fix, spec_.talker, sentence_));
  send(nmea::encode_gsa(gsa, spec_.talker, sentence_));
  send(nmea::encode_rmc(fix, spec_.talker, sentence_));
}

}  // namespace blockmap::hal::sim::detail
