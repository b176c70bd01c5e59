// Every parameter of localization (the seed's section II), with defaults for a Segway RMP with
// a consumer GPS receiver (about 2 m of slowly wandering error). Units are in the names.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace blockmap::localize {

struct LocalizeConfig {
  // Capacities, fixed at init. A history step is kept every history_interval_s of odometry;
  // history_steps of them make the fixed lag (512 x 0.25 s: about two minutes).
  std::size_t particle_count = 2000;
  std::size_t history_steps = 512;
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
  // standard deviation is user_range_error_m times its HDOP, at least min_gps_sigma_m.
  double user_range_error_m = 2.0;
  double min_gps_sigma_m = 0.5;
  double dgps_sigma_factor = 0.5;  // DGPS and RTK fixes are better than their HDOP says
  // A receiver's error wanders slowly: fixes a fraction of a second apart share most of it.
  // Weighing each as independent would believe GPS hundreds of times over and let the
  // particles chase its wander. Each fix is weighed with its sigma times
  // sqrt(gps_correlation_s / time since the last fix): per correlation time, GPS counts once.
  double gps_correlation_s = 60.0;
  // The paper's rule: particles farther than this many sigmas from the fix are not resampled.
  double resample_gate_sigmas = 3.0;
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
