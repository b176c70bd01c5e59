// Every parameter of localization (the seed's section II), with defaults for a Segway RMP with
// a consumer GPS receiver (about 2 m of slowly wandering error). Units are in the names.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace blockmap::localize {

struct LocalizeConfig {
  // Capacities, fixed at init. A history step is kept every history_interval_s of odometry;
  // history_steps of them make the fixed lag (240 x 0.25 s: one minute). 4,000 particles and
  // a minute of lag: 15 MB (docs/localize.md says why these).
  std::size_t particle_count = 4000;
  std::size_t history_steps = 240;
  double history_interval_s = 0.25;

  // Action model (the paper: odometry and IMU plus Gaussian noise). Each particle carries its
  // own distance scale (tyre pressure: the wheels report 1-2 % too much or too little) and
  // yaw-rate bias (the gyroscope's), drawn at start and walking slowly.
  double distance_noise_per_sqrt_m = 0.02;  // slip: sigma of the distance over one metre
  double yaw_rate_noise_radps = 0.01;       // the gyroscope's white noise, per sample
  double yaw_noise_per_sqrt_m = 0.002;      // terrain jolts: heading sigma over one metre
  double initial_scale_sigma = 0.02;        // spread of the distance scale at start
  double scale_walk_per_sqrt_m = 0.0005;    // how fast a particle's scale may drift
  double initial_yaw_rate_bias_sigma_radps = 0.01;
  double yaw_rate_bias_walk_radps_per_sqrt_s = 0.0002;
  double initial_position_sigma_m = 2.0;            // around the first fix
  double initial_yaw_sigma_rad = 3.14159265358979;  // unknown heading: the whole circle

  // Observation model (the paper: weights from the distance to the GPS fix). The fix's
  // horizontal RMS error is user_range_error_m times its HDOP (2.2 m x an open-sky HDOP of 0.9:
  // a 2 m receiver), at least min_gps_sigma_m.
  double user_range_error_m = 2.2;
  double min_gps_sigma_m = 0.5;
  double dgps_sigma_factor = 0.5;  // DGPS fixes are better than their HDOP says
  // Carrier-phase (RTK) fixes: their horizontal RMS error, whatever the HDOP (a fixed
  // solution is good to centimetres, a float one to decimetres). min_gps_sigma_m is for code
  // fixes only.
  double rtk_fixed_sigma_m = 0.03;
  double rtk_float_sigma_m = 0.3;
  // After a resampling on a carrier-phase fix, each particle's heading and gyroscope bias are
  // jittered by these (ParticleFilter::roughen says why).
  double rtk_yaw_roughening_rad = 0.003;
  double rtk_bias_roughening_radps = 0.001;
  // A receiver's error is not independent from fix to fix. gps_bias_share of its variance is
  // slow (orbits, clocks, the atmosphere: it wanders with gps_bias_correlation_s); the rest,
  // less a white floor of gps_white_sigma_m, is multipath, correlated over
  // gps_noise_correlation_s. Both parts are states of each particle, estimated by a Kalman
  // filter per particle (the particles stay in x, y, yaw), which odometry tells apart from the
  // motion. Weighing fixes as independent would believe GPS hundreds of times over and let
  // the particles chase its wander.
  double gps_bias_share = 0.36;
  double gps_bias_correlation_s = 60.0;
  double gps_noise_correlation_s = 2.0;
  double gps_white_sigma_m = 0.2;
  // Weights use the innovation's variance times this: a few thousand particles cover five
  // dimensions thinly, and exact weights let one multipath excursion collapse them onto a
  // wrong heading. Doubling it halves the mean error over ten drives (docs/localize.md).
  double gps_likelihood_inflation = 2.0;
  // The paper's rule: particles farther than this many sigmas (of the innovation) from the
  // fix are not resampled. At 3 sigma the rule dropped the particles near the truth during
  // multipath excursions and the filter lost the loop; 5 keeps it as a guard against wild
  // particles.
  double resample_gate_sigmas = 5.0;
  // A fix farther than this many sigmas (its own and the particles' spread) from the estimate
  // is an outlier (a multipath jump) and is left out; after max_rejected_fixes such fixes in a
  // row, the filter believes GPS again and starts over around it (recovery after an outage or
  // a wrong start).
  double outlier_gate_sigmas = 5.0;
  std::uint32_t max_rejected_fixes = 8;
  // Resample when the effective number of particles falls below this fraction of them.
  double resample_effective_fraction = 0.5;

  std::uint64_t seed = 1;
};

// Empty when the configuration is usable, otherwise what is wrong with it.
[[nodiscard]] std::string validate(const LocalizeConfig& config);

}  // namespace blockmap::localize
