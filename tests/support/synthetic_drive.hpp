// A synthetic drive with known truth for the particle filter: 300 s around a 60 m x 40 m
// loop at 1.2 m/s with the simulator's error models (tyre scale, gyroscope bias and noise,
// slip, a GPS error of 2 m RMS: 1.6 m of multipath correlated over 2 s and 1.2 m that wanders
// with a 60 s correlation time, as config/robots/paper_rmp.toml), and the scoring of a
// filter run over it. Shared by tests/localize, the accuracy-versus-particles benchmark and the
// path solvers' benchmark (tests/bench/solvers).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/random.hpp"
#include "blockmap/localize/particle_filter.hpp"

namespace blockmap::localize::synthetic {

inline constexpr double kPi = std::numbers::pi;
inline constexpr TimestampNs kOdometryPeriodNs = 10'000'000;  // 100 Hz
inline constexpr int kOdometryPerFix = 25;                    // GPS at 4 Hz

struct DriveOptions {
  double duration_s = 300.0;
  double distance_scale = 1.015;  // what the wheels report, per true metre
  double yaw_rate_bias_radps = 0.005;
  double gps_error_rms_m = 2.0;  // both parts together
  double gps_multipath_rms_m = 1.6;
  double gps_correlation_s = 60.0;
  double gps_multipath_correlation_s = 2.0;
  GpsCorrection gps_correction = GpsCorrection::kNone;  // what the fixes say they are
  double outage_from_s = -1.0;                          // GPS silent in [from, to)
  double outage_to_s = -1.0;
  std::uint64_t seed = 1;
};

struct Sample {
  TimestampNs stamp_ns = 0;
  double distance_m = 0.0;
  double yaw_rate_radps = 0.0;
  bool has_fix = false;
  GpsObservation fix;
  Pose2 truth;
};

// A 60 m x 40 m loop at 1.2 m/s with 4 m corner radius, starting heading north-east.
inline std::vector<Sample> drive(const DriveOptions& options) {
  Random random(options.seed, "test.drive");
  std::vector<Sample> samples;
  const double dt = 0.01;
  const double speed = 1.2;
  const double corner_rate = speed / 4.0;
  const double legs[4] = {60.0, 40.0, 60.0, 40.0};
  double x = 0.0;
  double y = 0.0;
  double yaw = 0.6;
  int leg = 0;
  double leg_left = legs[0];
  double turn_left = 0.0;
  // Each part of the GPS error is a Gauss-Markov process per axis, from its stationary state.
  struct Wander {
    double keep = 0.0;
    double sigma = 0.0;
    double x = 0.0;
    double y = 0.0;
    void step(Random& random) {
      x = keep * x + std::sqrt(1.0 - keep * keep) * sigma * random.gaussian();
      y = keep * y + std::sqrt(1.0 - keep * keep) * sigma * random.gaussian();
    }
  };
  const double slow_rms =
      std::sqrt(std::max(0.0, options.gps_error_rms_m * options.gps_error_rms_m -
                                  options.gps_multipath_rms_m * options.gps_multipath_rms_m));
  Wander slow{std::exp(-0.25 / options.gps_correlation_s), slow_rms / std::numbers::sqrt2};
  Wander multipath{std::exp(-0.25 / options.gps_multipath_correlation_s),
                   options.gps_multipath_rms_m / std::numbers::sqrt2};
  for (Wander* w : {&slow, &multipath}) {
    w->x = w->sigma * random.gaussian();
    w->y = w->sigma * random.gaussian();
  }
  const auto steps = static_cast<int>(options.duration_s / dt);
  for (int k = 1; k <= steps; ++k) {
    const double rate = turn_left > 0.0 ? corner_rate : 0.0;
    const double step_m = speed * dt;
    yaw += rate * dt;
    x += step_m * std::cos(yaw);
    y += step_m * std::sin(yaw);
    if (turn_left > 0.0) {
      turn_left -= rate * dt;
    } else if ((leg_left -= step_m) <= 0.0) {
      leg = (leg + 1) % 4;
      leg_left = legs[leg];
      turn_left = kPi / 2.0;
    }
    Sample s;
    s.stamp_ns = k * kOdometryPeriodNs;
    s.distance_m = step_m * options.distance_scale * (1.0 + 0.01 * random.gaussian());
    s.yaw_rate_radps = rate + options.yaw_rate_bias_radps + 0.01 * random.gaussian();
    s.truth = Pose2{s.stamp_ns, x, y, std::remainder(yaw, 2.0 * kPi)};
    if (k % kOdometryPerFix == 0) {
      slow.step(random);
      multipath.step(random);
      const double t = static_cast<double>(k) * dt;
      s.has_fix = !(t >= options.outage_from_s && t < options.outage_to_s);
      s.fix = GpsObservation{s.stamp_ns, x + slow.x + multipath.x, y + slow.y + multipath.y, 0.9,
                             options.gps_correction};
    }
    samples.push_back(s);
  }
  return samples;
}

// The drive's odometry dead-reckoned with its scale and gyroscope bias taken out but for
// what calibration leaves (0.2 % of distance, `left_bias_radps` of turn rate), from the true
// start: the shape a calibrated dead reckoning or a scan matcher gives.
inline std::vector<Pose2> calibrated_odometry(const std::vector<Sample>& samples,
                                              const DriveOptions& drive, double left_bias_radps) {
  std::vector<Pose2> odometry;
  odometry.reserve(samples.size());
  Pose2 pose{0, 0.0, 0.0, 0.6};
  for (const Sample& s : samples) {
    const double dt_s = 0.01;
    const double distance_m = s.distance_m / drive.distance_scale * 1.002;
    const double turn_rad = (s.yaw_rate_radps - drive.yaw_rate_bias_radps + left_bias_radps) * dt_s;
    pose.x_m += distance_m * std::cos(pose.yaw_rad + 0.5 * turn_rad);
    pose.y_m += distance_m * std::sin(pose.yaw_rad + 0.5 * turn_rad);
    pose.yaw_rad = std::remainder(pose.yaw_rad + turn_rad, 2.0 * kPi);
    pose.stamp_ns = s.stamp_ns;
    odometry.push_back(pose);
  }
  return odometry;
}

struct FilterFixture {
  explicit FilterFixture(const LocalizeConfig& config = {})
      : arena(ParticleFilter::arena_bytes(config)) {
    filter.init(arena, config);
    arena.seal();
  }
  Arena arena;
  ParticleFilter filter;
};

inline double heading_error_rad(double a, double b) {
  return std::abs(std::remainder(a - b, 2.0 * kPi));
}

struct RunErrors {
  double filter_rms_m = 0.0;
  double smoothed_rms_m = 0.0;
  double gps_rms_m = 0.0;
  double heading_rms_deg = 0.0;
  double smoothed_heading_rms_deg = 0.0;
  double worst_in_outage_m = 0.0;
};

// Runs the filter over a drive and scores it after the first `settle_s` seconds.
inline RunErrors run(ParticleFilter& filter, const std::vector<Sample>& samples,
                     const DriveOptions& options, double settle_s = 60.0) {
  RunErrors errors;
  std::vector<Pose2> smoothed;
  std::vector<Pose2> drained(64);
  double filter_sq = 0.0;
  double gps_sq = 0.0;
  double heading_sq = 0.0;
  std::size_t scored = 0;
  std::size_t fixes = 0;
  const auto settle_ns = static_cast<TimestampNs>(settle_s * 1e9);
  for (const Sample& s : samples) {
    filter.predict(s.stamp_ns, s.distance_m, s.yaw_rate_radps);
    if (s.has_fix) {
      static_cast<void>(filter.update(s.fix));
      if (s.stamp_ns >= settle_ns) {
        gps_sq +=
            std::pow(s.fix.east_m - s.truth.x_m, 2) + std::pow(s.fix.north_m - s.truth.y_m, 2);
        ++fixes;
      }
    }
    const std::size_t n = filter.drain_final(drained);
    smoothed.insert(smoothed.end(), drained.begin(),
                    drained.begin() + static_cast<std::ptrdiff_t>(n));
    if (filter.started() && s.stamp_ns >= settle_ns && s.stamp_ns % (10 * kOdometryPeriodNs) == 0) {
      const Pose2 e = filter.estimate();
      const double sq = std::pow(e.x_m - s.truth.x_m, 2) + std::pow(e.y_m - s.truth.y_m, 2);
      filter_sq += sq;
      heading_sq += std::pow(heading_error_rad(e.yaw_rad, s.truth.yaw_rad), 2);
      ++scored;
      const double t = static_cast<double>(s.stamp_ns) * 1e-9;
      if (t >= options.outage_from_s && t < options.outage_to_s) {
        errors.worst_in_outage_m = std::max(errors.worst_in_outage_m, std::sqrt(sq));
      }
    }
  }
  std::vector<Pose2> rest(filter.history_size());
  rest.resize(filter.smoothed_window(rest));
  smoothed.insert(smoothed.end(), rest.begin(), rest.end());
  // Smoothed poses are at history steps: compare each with the truth at its stamp.
  double smoothed_sq = 0.0;
  double smoothed_heading_sq = 0.0;
  std::size_t smoothed_scored = 0;
  for (const Pose2& p : smoothed) {
    if (p.stamp_ns < settle_ns) {
      continue;
    }
    const auto index = static_cast<std::size_t>(p.stamp_ns / kOdometryPeriodNs) - 1;
    const Pose2& truth = samples[std::min(index, samples.size() - 1)].truth;
    smoothed_sq += std::pow(p.x_m - truth.x_m, 2) + std::pow(p.y_m - truth.y_m, 2);
    smoothed_heading_sq += std::pow(heading_error_rad(p.yaw_rad, truth.yaw_rad), 2);
    ++smoothed_scored;
  }
  errors.filter_rms_m =
      std::sqrt(filter_sq / static_cast<double>(std::max<std::size_t>(scored, 1)));
  errors.heading_rms_deg =
      std::sqrt(heading_sq / static_cast<double>(std::max<std::size_t>(scored, 1))) * 180.0 / kPi;
  errors.gps_rms_m = std::sqrt(gps_sq / static_cast<double>(std::max<std::size_t>(fixes, 1)));
  errors.smoothed_rms_m =
      std::sqrt(smoothed_sq / static_cast<double>(std::max<std::size_t>(smoothed_scored, 1)));
  errors.smoothed_heading_rms_deg =
      std::sqrt(smoothed_heading_sq /
                static_cast<double>(std::max<std::size_t>(smoothed_scored, 1))) *
      180.0 / kPi;
  return errors;
}

}  // namespace blockmap::localize::synthetic
