#include "blockmap/localize/localize_config.hpp"

#include <cstdint>
#include <limits>

namespace blockmap::localize {

std::string validate(const LocalizeConfig& c) {
  // History entries keep a 32-bit parent index; the quantile table needs a few particles.
  if (c.particle_count < 2 || c.particle_count > std::numeric_limits<std::uint32_t>::max()) {
    return "particle_count must be at least 2";
  }
  if (c.history_steps < 2) {
    return "history_steps must be at least 2";
  }
  if (!(c.history_interval_s > 0.0)) {
    return "history_interval_s must be > 0";
  }
  const bool noise_ok = c.distance_noise_per_sqrt_m >= 0.0 && c.yaw_rate_noise_radps >= 0.0 &&
                        c.yaw_noise_per_sqrt_m >= 0.0 && c.initial_scale_sigma >= 0.0 &&
                        c.scale_walk_per_sqrt_m >= 0.0 &&
                        c.initial_yaw_rate_bias_sigma_radps >= 0.0 &&
                        c.yaw_rate_bias_walk_radps_per_sqrt_s >= 0.0 &&
                        c.initial_position_sigma_m >= 0.0 && c.initial_yaw_sigma_rad >= 0.0;
  if (!noise_ok) {
    return "noise and spread parameters must be >= 0";
  }
  if (!(c.user_range_error_m > 0.0) || !(c.min_gps_sigma_m > 0.0) || !(c.dgps_sigma_factor > 0.0) ||
      !(c.rtk_fixed_sigma_m > 0.0) || !(c.rtk_float_sigma_m > 0.0) ||
      !(c.rtk_yaw_roughening_rad >= 0.0) || !(c.rtk_bias_roughening_radps >= 0.0)) {
    return "user_range_error_m, min_gps_sigma_m, dgps_sigma_factor, rtk_fixed_sigma_m and "
           "rtk_float_sigma_m must be > 0, the rtk_*_roughening >= 0";
  }
  // Some of the error must be fast: a fix with only a slow error would pin the particles.
  if (!(c.gps_bias_share >= 0.0 && c.gps_bias_share <= 0.95)) {
    return "gps_bias_share must be in [0, 0.95]";
  }
  if (!(c.gps_bias_correlation_s > 0.0) || !(c.gps_noise_correlation_s >= 0.0)) {
    return "gps_bias_correlation_s must be > 0 and gps_noise_correlation_s >= 0";
  }
  if (!(c.gps_likelihood_inflation >= 1.0)) {
    return "gps_likelihood_inflation must be >= 1";
  }
  if (!(c.gps_white_sigma_m > 0.0)) {
    return "gps_white_sigma_m must be > 0";
  }
  if (!(c.resample_gate_sigmas > 0.0) || !(c.outlier_gate_sigmas > 0.0)) {
    return "resample_gate_sigmas and outlier_gate_sigmas must be > 0";
  }
  if (c.max_rejected_fixes < 1) {
    return "max_rejected_fixes must be at least 1";
  }
  if (!(c.resample_effective_fraction > 0.0 && c.resample_effective_fraction <= 1.0)) {
    return "resample_effective_fraction must be in (0, 1]";
  }
  return {};
}

}  // namespace blockmap::localize
