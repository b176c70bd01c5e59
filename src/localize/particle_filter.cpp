#include "blockmap/localize/particle_filter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"

namespace blockmap::localize {
namespace {

constexpr std::size_t kGaussianTableBits = 12;
constexpr std::size_t kGaussianTableSize = std::size_t{1} << kGaussianTableBits;
constexpr std::size_t kFinalCapacity = 64;  // finalized poses waiting to be drained

// The standard normal quantile (inverse CDF), by bisection on std::erfc: run once per table
// entry at init, so exactness matters more than speed.
double normal_quantile(double p) noexcept {
  double low = -10.0;
  double high = 10.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (low + high);
    if (0.5 * std::erfc(-mid / std::numbers::sqrt2) < p) {
      low = mid;
    } else {
      high = mid;
    }
  }
  return 0.5 * (low + high);
}

// Turns below this take the rotation by series (error below 1e-12 per step); larger ones
// call cos and sin.
constexpr double kSmallTurnRad = 0.05;

// A batch of odometry is applied as one arc: at most this much turn (the chord of an arc
// that turns 0.02 rad is 0.002 % shorter than the arc), distance, or base samples.
constexpr double kMaxPendingTurnRad = 0.02;
constexpr double kMaxPendingDistanceM = 0.5;
constexpr std::uint32_t kMaxPendingSteps = 8;

// cos and sin of a small angle by their series: 1 - a^2/2 + a^4/24 and a - a^3/6 + a^5/120.
std::pair<double, double> small_rotation(double a) noexcept {
  const double a2 = a * a;
  return {1.0 - a2 * (0.5 - a2 * (1.0 / 24.0)), a * (1.0 - a2 * (1.0 / 6.0 - a2 * (1.0 / 120.0)))};
}

// An angle a small step outside (-pi, pi] back inside, without a division.
double wrap_small_step(double angle_rad) noexcept {
  constexpr double kPi = std::numbers::pi;
  if (angle_rad > kPi) {
    return angle_rad - 2.0 * kPi;
  }
  return angle_rad <= -kPi ? angle_rad + 2.0 * kPi : angle_rad;
}

}  // namespace

void ParticleFilter::init(Arena& arena, const LocalizeConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), "invalid localize configuration (validate() says why)");
  config_ = config;
  random_ = Random(config.seed, "localize.particles");
  count_ = config.particle_count;
  const char* owner = "localize.particle_filter";
  // Stratified quantiles: entry i is the quantile at (i + 0.5) / size, so the table is the
  // normal distribution discretized, truncated at about 3.5 sigma.
  gaussian_table_ = arena.allocate_array<float>(kGaussianTableSize, owner);
  for (std::size_t i = 0; i < kGaussianTableSize; ++i) {
    gaussian_table_[i] = static_cast<float>(
        normal_quantile((static_cast<double>(i) + 0.5) / static_cast<double>(kGaussianTableSize)));
  }
  x_m_ = arena.allocate_array<double>(count_, owner);
  y_m_ = arena.allocate_array<double>(count_, owner);
  yaw_rad_ = arena.allocate_array<double>(count_, owner);
  cos_yaw_ = arena.allocate_array<double>(count_, owner);
  sin_yaw_ = arena.allocate_array<double>(count_, owner);
  scale_ = arena.allocate_array<double>(count_, owner);
  yaw_rate_bias_radps_ = arena.allocate_array<double>(count_, owner);
  gps_slow_x_m_ = arena.allocate_array<double>(count_, owner);
  gps_slow_y_m_ = arena.allocate_array<double>(count_, owner);
  gps_fast_x_m_ = arena.allocate_array<double>(count_, owner);
  gps_fast_y_m_ = arena.allocate_array<double>(count_, owner);
  weight_ = arena.allocate_array<double>(count_, owner);
  ancestor_ = arena.allocate_array<std::uint32_t>(count_, owner);
  chosen_ = arena.allocate_array<std::uint32_t>(count_, owner);
  scratch_ = arena.allocate_array<double>(count_, owner);
  history_ = arena.allocate_array<HistoryEntry>(config.history_steps * count_, owner);
  history_stamps_ = arena.allocate_array<TimestampNs>(config.history_steps, owner);
  history_identity_ = arena.allocate_array<std::uint8_t>(config.history_steps, owner);
  trace_ = arena.allocate_array<std::uint32_t>(count_, owner);
  trace_weight_ = arena.allocate_array<double>(count_, owner);
  lineage_slot_ = arena.allocate_array<std::uint32_t>(count_, owner);
  lineage_seen_ = arena.allocate_array<std::uint32_t>(count_, owner);
  final_ = arena.allocate_array<Pose2>(kFinalCapacity, owner);
}

std::size_t ParticleFilter::arena_bytes(const LocalizeConfig& config) noexcept {
  constexpr std::size_t kAlignment = Arena::kMaxPaddingBytes;
  const std::size_t n = config.particle_count;
  return kGaussianTableSize * sizeof(float) + 14 * n * sizeof(double) +
         5 * n * sizeof(std::uint32_t) + config.history_steps * n * sizeof(HistoryEntry) +
         config.history_steps * (sizeof(TimestampNs) + 1) + kFinalCapacity * sizeof(Pose2) +
         20 * kAlignment;
}

std::size_t ParticleFilter::memory_bytes() const noexcept {
  return gaussian_table_.size_bytes() + x_m_.size_bytes() + y_m_.size_bytes() +
         yaw_rad_.size_bytes() + cos_yaw_.size_bytes() + sin_yaw_.size_bytes() +
         scale_.size_bytes() + yaw_rate_bias_radps_.size_bytes() + gps_slow_x_m_.size_bytes() +
         gps_slow_y_m_.size_bytes() + gps_fast_x_m_.size_bytes() + gps_fast_y_m_.size_bytes() +
         weight_.size_bytes() + ancestor_.size_bytes() + chosen_.size_bytes() +
         scratch_.size_bytes() + history_.size_bytes() + history_stamps_.size_bytes() +
         history_identity_.size_bytes() + trace_.size_bytes() + trace_weight_.size_bytes() +
         lineage_slot_.size_bytes() + lineage_seen_.size_bytes() + final_.size_bytes();
}

double ParticleFilter::gaussian() noexcept {
  // Five table indices from each 64-bit draw.
  if (random_bits_left_ < kGaussianTableBits) {
    random_bits_ = random_.next();
    random_bits_left_ = 64;
  }
  const auto index = static_cast<std::size_t>(random_bits_ & (kGaussianTableSize - 1));
  random_bits_ >>= kGaussianTableBits;
  random_bits_left_ -= static_cast<std::uint32_t>(kGaussianTableBits);
  return static_cast<double>(gaussian_table_[index]);
}

void ParticleFilter::predict(TimestampNs stamp_ns, double distance_m,
                             double yaw_rate_radps) noexcept {
  ++version_;
  const double dt_s = have_stamp_ ? std::max(0.0, seconds_from_ns(stamp_ns - last_stamp_ns_)) : 0.0;
  have_stamp_ = true;
  last_stamp_ns_ = std::max(last_stamp_ns_, stamp_ns);
  if (!started_) {
    return;
  }
  ++counters_.predictions;
  accumulate_motion(dt_s, distance_m, yaw_rate_radps);
  // The particles move once per batch of odometry: before a history step, when the batch
  // has turned or travelled enough that one arc no longer stands for it, or is long.
  const bool history_due = stamp_ns >= next_history_ns_;
  if (history_due || std::abs(pending_.turn_rad) >= kMaxPendingTurnRad ||
      std::abs(pending_.distance_m) >= kMaxPendingDistanceM || pending_.steps >= kMaxPendingSteps) {
    apply_motion();
  }
  if (history_due) {
    push_history(stamp_ns);
  }
}

void ParticleFilter::accumulate_motion(double dt_s, double distance_m,
                                       double yaw_rate_radps) noexcept {
  // Each step's noise is independent, so a batch's noise is one draw with the summed
  // variances; the particles' scale and bias act on the summed distance and time alike.
  const double travelled_m = std::abs(distance_m);
  const double yaw_rate_noise = config_.yaw_rate_noise_radps * dt_s;
  pending_.distance_m += distance_m;
  pending_.turn_rad += yaw_rate_radps * dt_s;
  pending_.dt_s += dt_s;
  pending_.distance_variance_m2 +=
      config_.distance_noise_per_sqrt_m * config_.distance_noise_per_sqrt_m * travelled_m;
  pending_.yaw_variance_rad2 += yaw_rate_noise * yaw_rate_noise + config_.yaw_noise_per_sqrt_m *
                                                                      config_.yaw_noise_per_sqrt_m *
                                                                      travelled_m;
  pending_.scale_variance +=
      config_.scale_walk_per_sqrt_m * config_.scale_walk_per_sqrt_m * travelled_m;
  pending_.bias_variance_radps2 += config_.yaw_rate_bias_walk_radps_per_sqrt_s *
                                   config_.yaw_rate_bias_walk_radps_per_sqrt_s * dt_s;
  ++pending_.steps;
}

void ParticleFilter::apply_motion() noexcept {
  if (pending_.steps == 0) {
    return;
  }
  const PendingMotion motion = pending_;
  pending_ = PendingMotion{};
  const double distance_sigma = std::sqrt(motion.distance_variance_m2);
  const double yaw_sigma = std::sqrt(motion.yaw_variance_rad2);
  const double scale_sigma = std::sqrt(motion.scale_variance);
  const double bias_sigma = std::sqrt(motion.bias_variance_radps2);
  for (std::size_t i = 0; i < count_; ++i) {
    // Each particle's own wheels and gyroscope: its scale and bias, plus this batch's noise.
    const double d = motion.distance_m * scale_[i] + distance_sigma * gaussian();
    const double turn =
        motion.turn_rad - yaw_rate_bias_radps_[i] * motion.dt_s + yaw_sigma * gaussian();
    const double next_yaw = yaw_rad_[i] + turn;
    if (std::abs(turn) < kSmallTurnRad) {
      // Along the arc's mid-point heading, by rotating the particle's (cos, sin) of yaw by
      // half the turn twice: no trigonometric call per particle and batch.
      const auto [c_half, s_half] = small_rotation(0.5 * turn);
      const double c_mid = cos_yaw_[i] * c_half - sin_yaw_[i] * s_half;
      const double s_mid = sin_yaw_[i] * c_half + cos_yaw_[i] * s_half;
      x_m_[i] += d * c_mid;
      y_m_[i] += d * s_mid;
      cos_yaw_[i] = c_mid * c_half - s_mid * s_half;
      sin_yaw_[i] = s_mid * c_half + c_mid * s_half;
      yaw_rad_[i] = wrap_small_step(next_yaw);
    } else {
      const double heading = yaw_rad_[i] + 0.5 * turn;
      x_m_[i] += d * std::cos(heading);
      y_m_[i] += d * std::sin(heading);
      yaw_rad_[i] = wrap_angle(next_yaw);
      cos_yaw_[i] = std::cos(yaw_rad_[i]);
      sin_yaw_[i] = std::sin(yaw_rad_[i]);
    }
    scale_[i] += scale_sigma * gaussian();
    yaw_rate_bias_radps_[i] += bias_sigma * gaussian();
  }
}

double ParticleFilter::fix_sigma_m(const GpsObservation& fix) const noexcept {
  // Per axis: the horizontal RMS shared by east and north.
  switch (fix.correction) {
    case GpsCorrection::kRtkFixed:
      return config_.rtk_fixed_sigma_m / std::numbers::sqrt2;
    case GpsCorrection::kRtkFloat:
      return config_.rtk_float_sigma_m / std::numbers::sqrt2;
    case GpsCorrection::kDifferential:
    case GpsCorrection::kNone:
      break;
  }
  // A code fix: UERE x HDOP.
  const double differential =
      fix.correction == GpsCorrection::kDifferential ? config_.dgps_sigma_factor : 1.0;
  const double sigma =
      config_.user_range_error_m * std::max(fix.hdop, 0.0) * differential / std::numbers::sqrt2;
  return std::max(sigma, config_.min_gps_sigma_m);
}

double ParticleFilter::start_spread_m(const GpsObservation& fix) const noexcept {
  return std::min(config_.initial_position_sigma_m, 3.0 * fix_sigma_m(fix));
}

ParticleFilter::FixError ParticleFilter::fix_error(const GpsObservation& fix) const noexcept {
  const double sigma_m = fix_sigma_m(fix);
  FixError error;
  if (carrier_phase(fix.correction)) {
    // Centimetres, correlated over seconds at most: taken as white. Each particle's estimate
    // of a slow error would otherwise grow to hide a wrong position: after the heading's
    // first seconds every particle has drifted alike, and none is left near the fix to
    // select, while a few centimetres of error state hide a decimetre within the gates.
    error.white_variance_m2 = sigma_m * sigma_m;
    return error;
  }
  const double white_m = config_.gps_white_sigma_m;
  error.slow_variance_m2 = config_.gps_bias_share * sigma_m * sigma_m;
  error.fast_variance_m2 =
      std::max(0.0, (1.0 - config_.gps_bias_share) * sigma_m * sigma_m - white_m * white_m);
  error.white_variance_m2 = white_m * white_m;
  return error;
}

GpsOutcome ParticleFilter::update(const GpsObservation& fix) noexcept {
  ++version_;
  apply_motion();  // the particles where the odometry says they are at the fix
  const FixError error = fix_error(fix);
  if (!started_) {
    start_at(fix, start_spread_m(fix), false);
    return GpsOutcome::kStarted;
  }
  advance_gps_error(seconds_from_ns(fix.stamp_ns - gps_error_stamp_ns_), error);
  gps_error_stamp_ns_ = std::max(gps_error_stamp_ns_, fix.stamp_ns);
  if (is_outlier(fix, error)) {
    ++counters_.fixes_rejected;
    if (++rejected_in_a_row_ < config_.max_rejected_fixes) {
      return GpsOutcome::kRejected;
    }
    // GPS has disagreed for too long: the filter is wrong, not the receiver.
    ++counters_.recoveries;
    start_at(fix, std::max(fix_sigma_m(fix), start_spread_m(fix)), true);
    return GpsOutcome::kRecovered;
  }
  rejected_in_a_row_ = 0;
  ++counters_.fixes_used;
  weigh(fix, error);
  if (effective_particles() < config_.resample_effective_fraction * static_cast<double>(count_)) {
    resample();
    if (carrier_phase(fix.correction)) {
      roughen();
    }
  }
  return GpsOutcome::kUsed;
}

void ParticleFilter::advance_gps_error(double dt_s, const FixError& error) noexcept {
  // Both parts of the receiver's error are Gauss-Markov processes: their means decay towards
  // zero and their covariance towards the stationary one. The covariance is the same for
  // every particle (the same fixes at the same times), so it is kept once.
  const double keep_slow = std::exp(-std::max(dt_s, 0.0) / config_.gps_bias_correlation_s);
  const double keep_fast = config_.gps_noise_correlation_s > 0.0
                               ? std::exp(-std::max(dt_s, 0.0) / config_.gps_noise_correlation_s)
                               : 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    gps_slow_x_m_[i] *= keep_slow;
    gps_slow_y_m_[i] *= keep_slow;
    gps_fast_x_m_[i] *= keep_fast;
    gps_fast_y_m_[i] *= keep_fast;
  }
  GpsErrorCovariance& p = gps_covariance_;
  p.slow_slow =
      keep_slow * keep_slow * p.slow_slow + (1.0 - keep_slow * keep_slow) * error.slow_variance_m2;
  p.fast_fast =
      keep_fast * keep_fast * p.fast_fast + (1.0 - keep_fast * keep_fast) * error.fast_variance_m2;
  p.slow_fast *= keep_slow * keep_fast;
}

double ParticleFilter::fix_innovation_variance_m2(const FixError& error) const noexcept {
  // Per axis: the fix is position + slow + fast + white.
  const GpsErrorCovariance& p = gps_covariance_;
  return p.slow_slow + 2.0 * p.slow_fast + p.fast_fast + error.white_variance_m2;
}

bool ParticleFilter::is_outlier(const GpsObservation& fix, const FixError& error) const noexcept {
  // The fix against where the particles expect it (position plus their estimate of the
  // receiver's error), allowing for the expectation's variance and the particles' spread.
  const PositionStats where = expected_fix_stats(fix);
  const double innovation_m = std::hypot(fix.east_m - where.mean_x_m, fix.north_m - where.mean_y_m);
  const double gate_m =
      config_.outlier_gate_sigmas *
      std::sqrt(2.0 * fix_innovation_variance_m2(error) + where.spread_m * where.spread_m);
  return innovation_m > gate_m;
}

void ParticleFilter::start_at(const GpsObservation& fix, double sigma_m,
                              bool keep_heading) noexcept {
  // Where the robot may be, given the fix: around it by sigma_m. Each particle's estimate of
  // the receiver's error is then what the fix says it is (fix - position), shared between the
  // error's parts by their variances.
  const FixError error = fix_error(fix);
  const double total_m2 = error.slow_variance_m2 + error.fast_variance_m2 + error.white_variance_m2;
  const double slow_gain = error.slow_variance_m2 / total_m2;
  const double fast_gain = error.fast_variance_m2 / total_m2;
  gps_covariance_.slow_slow = error.slow_variance_m2 * (1.0 - slow_gain);
  gps_covariance_.fast_fast = error.fast_variance_m2 * (1.0 - fast_gain);
  gps_covariance_.slow_fast = -slow_gain * error.fast_variance_m2;
  // Particles drawn wider than the fix's own error are weighed back to it (importance
  // weights: the fix's density over the drawing's), so that a particle far from the fix does
  // not start as likely as one near it.
  const double draw_variance_m2 = std::max(sigma_m * sigma_m, total_m2);
  const double draw_sigma_m = std::sqrt(draw_variance_m2);
  const double reweigh = 0.5 / total_m2 - 0.5 / draw_variance_m2;
  for (std::size_t i = 0; i < count_; ++i) {
    if (!keep_heading) {
      // Unknown heading: spread evenly over initial_yaw_sigma_rad either side of east.
      const double share = (static_cast<double>(i) + 0.5) / static_cast<double>(count_);
      yaw_rad_[i] = wrap_angle((2.0 * share - 1.0) * config_.initial_yaw_sigma_rad);
    }
    cos_yaw_[i] = std::cos(yaw_rad_[i]);
    sin_yaw_[i] = std::sin(yaw_rad_[i]);
    // The antenna drawn around the fix; the robot frame's origin behind it by the mount as
    // this particle's heading turns it.
    const double dx = draw_sigma_m * gaussian();
    const double dy = draw_sigma_m * gaussian();
    x_m_[i] =
        fix.east_m + dx - (cos_yaw_[i] * fix.antenna_ahead_m - sin_yaw_[i] * fix.antenna_left_m);
    y_m_[i] =
        fix.north_m + dy - (sin_yaw_[i] * fix.antenna_ahead_m + cos_yaw_[i] * fix.antenna_left_m);
    weight_[i] = std::exp(-(dx * dx + dy * dy) * reweigh);
    gps_slow_x_m_[i] = -slow_gain * dx;
    gps_slow_y_m_[i] = -slow_gain * dy;
    gps_fast_x_m_[i] = -fast_gain * dx;
    gps_fast_y_m_[i] = -fast_gain * dy;
    if (!keep_heading) {
      scale_[i] = 1.0 + config_.initial_scale_sigma * gaussian();
      yaw_rate_bias_radps_[i] = config_.initial_yaw_rate_bias_sigma_radps * gaussian();
    }
  }
  normalize_weights();
  if (!started_ || !keep_heading) {
    // A new start: the history starts over too.
    history_size_ = 0;
    for (std::size_t i = 0; i < count_; ++i) {
      ancestor_[i] = static_cast<std::uint32_t>(i);
    }
    resampled_since_push_ = false;
  }
  started_ = true;
  rejected_in_a_row_ = 0;
  gps_error_stamp_ns_ = fix.stamp_ns;
  const TimestampNs stamp_ns = std::max(fix.stamp_ns, last_stamp_ns_);
  push_history(stamp_ns);
}

void ParticleFilter::start_at_pose(const Pose2& pose, double position_sigma_m,
                                   double yaw_sigma_rad) noexcept {
  // Nothing is known of the receiver's error yet: its stationary variances, and no estimate.
  const FixError error = fix_error(GpsObservation{});
  gps_covariance_ = {error.slow_variance_m2, 0.0, error.fast_variance_m2};
  for (std::size_t i = 0; i < count_; ++i) {
    x_m_[i] = pose.x_m + position_sigma_m * gaussian();
    y_m_[i] = pose.y_m + position_sigma_m * gaussian();
    yaw_rad_[i] = wrap_angle(pose.yaw_rad + yaw_sigma_rad * gaussian());
    cos_yaw_[i] = std::cos(yaw_rad_[i]);
    sin_yaw_[i] = std::sin(yaw_rad_[i]);
    weight_[i] = 1.0;
    gps_slow_x_m_[i] = 0.0;
    gps_slow_y_m_[i] = 0.0;
    gps_fast_x_m_[i] = 0.0;
    gps_fast_y_m_[i] = 0.0;
    scale_[i] = 1.0 + config_.initial_scale_sigma * gaussian();
    yaw_rate_bias_radps_[i] = config_.initial_yaw_rate_bias_sigma_radps * gaussian();
    ancestor_[i] = static_cast<std::uint32_t>(i);
  }
  normalize_weights();
  history_size_ = 0;
  resampled_since_push_ = false;
  started_ = true;
  rejected_in_a_row_ = 0;
  gps_error_stamp_ns_ = pose.stamp_ns;
  push_history(std::max(pose.stamp_ns, last_stamp_ns_));
}

void ParticleFilter::weigh(const GpsObservation& fix, const FixError& error) noexcept {
  // The paper's observation model, a Gaussian of the distance to the fix, here from where
  // each particle expects the fix: its position plus its estimate of the receiver's error.
  // Particles beyond the gate get no weight: the paper does not resample them. Then each
  // particle's error estimate takes its share of the innovation: a Kalman update whose gain
  // is the same for every particle.
  const double innovation_variance_m2 = fix_innovation_variance_m2(error);
  const double inverse_two_variance =
      0.5 / (config_.gps_likelihood_inflation * innovation_variance_m2);
  const double gate_squared =
      config_.resample_gate_sigmas * config_.resample_gate_sigmas * innovation_variance_m2;
  GpsErrorCovariance& p = gps_covariance_;
  const double slow_gain = (p.slow_slow + p.slow_fast) / innovation_variance_m2;
  const double fast_gain = (p.slow_fast + p.fast_fast) / innovation_variance_m2;
  double total = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    const double dx = fix.east_m - antenna_x_m(i, fix) - gps_slow_x_m_[i] - gps_fast_x_m_[i];
    const double dy = fix.north_m - antenna_y_m(i, fix) - gps_slow_y_m_[i] - gps_fast_y_m_[i];
    const double squared = dx * dx + dy * dy;
    scratch_[i] = squared;
    weight_[i] *= squared > gate_squared ? 0.0 : std::exp(-squared * inverse_two_variance);
    total += weight_[i];
    gps_slow_x_m_[i] += slow_gain * dx;
    gps_slow_y_m_[i] += slow_gain * dy;
    gps_fast_x_m_[i] += fast_gain * dx;
    gps_fast_y_m_[i] += fast_gain * dy;
  }
  if (total <= 0.0) {
    // Every particle beyond the gate, yet the fix passed the outlier test (the particles are
    // spread wide): keep them all, weighed by distance alone.
    for (std::size_t i = 0; i < count_; ++i) {
      weight_[i] = 1.0 / (1.0 + scratch_[i] * inverse_two_variance);
    }
  }
  // P - K S K^T.
  p.slow_slow -= slow_gain * slow_gain * innovation_variance_m2;
  p.slow_fast -= slow_gain * fast_gain * innovation_variance_m2;
  p.fast_fast -= fast_gain * fast_gain * innovation_variance_m2;
  normalize_weights();
}

void ParticleFilter::normalize_weights() noexcept {
  double total = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    total += weight_[i];
  }
  const double inverse = total > 0.0 ? 1.0 / total : 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    weight_[i] = total > 0.0 ? weight_[i] * inverse : 1.0 / static_cast<double>(count_);
  }
}

double ParticleFilter::effective_particles() const noexcept {
  double sum_squares = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    sum_squares += weight_[i] * weight_[i];
  }
  return sum_squares > 0.0 ? 1.0 / sum_squares : 0.0;
}

void ParticleFilter::resample() noexcept {
  // Systematic resampling: one random offset, N evenly spaced pointers into the cumulative
  // weights. O(N), and a particle of weight w is copied N w times, give or take one.
  ++counters_.resamplings;
  const double step = 1.0 / static_cast<double>(count_);
  double pointer = random_.uniform() * step;
  double cumulative = weight_[0];
  std::size_t source = 0;
  for (std::size_t i = 0; i < count_; ++i) {
    while (pointer > cumulative && source + 1 < count_) {
      cumulative += weight_[++source];
    }
    chosen_[i] = static_cast<std::uint32_t>(source);
    pointer += step;
  }
  const auto gather = [&](std::span<double> values) {
    for (std::size_t i = 0; i < count_; ++i) {
      scratch_[i] = values[chosen_[i]];
    }
    std::copy_n(scratch_.begin(), count_, values.begin());
  };
  gather(x_m_);
  gather(y_m_);
  gather(yaw_rad_);
  gather(cos_yaw_);
  gather(sin_yaw_);
  gather(scale_);
  gather(yaw_rate_bias_radps_);
  gather(gps_slow_x_m_);
  gather(gps_slow_y_m_);
  gather(gps_fast_x_m_);
  gather(gps_fast_y_m_);
  // The ancestry follows the copies (trace_ is free scratch between calls).
  for (std::size_t i = 0; i < count_; ++i) {
    trace_[i] = ancestor_[chosen_[i]];
  }
  std::copy_n(trace_.begin(), count_, ancestor_.begin());
  std::fill_n(weight_.begin(), count_, step);
  resampled_since_push_ = true;
}

void ParticleFilter::roughen() noexcept {
  for (std::size_t i = 0; i < count_; ++i) {
    yaw_rad_[i] = wrap_angle(yaw_rad_[i] + config_.rtk_yaw_roughening_rad * gaussian());
    cos_yaw_[i] = std::cos(yaw_rad_[i]);
    sin_yaw_[i] = std::sin(yaw_rad_[i]);
    yaw_rate_bias_radps_[i] += config_.rtk_bias_roughening_radps * gaussian();
  }
}

Pose2 ParticleFilter::estimate() const noexcept {
  Pose2 pose;
  pose.stamp_ns = last_stamp_ns_;
  double sin_sum = 0.0;
  double cos_sum = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    pose.x_m += weight_[i] * x_m_[i];
    pose.y_m += weight_[i] * y_m_[i];
    sin_sum += weight_[i] * sin_yaw_[i];
    cos_sum += weight_[i] * cos_yaw_[i];
  }
  pose.yaw_rad = std::atan2(sin_sum, cos_sum);
  if (pending_.steps > 0) {
    // The odometry not yet applied to the particles, applied to their mean.
    const double turn_rad = pending_.turn_rad - mean_yaw_rate_bias_radps() * pending_.dt_s;
    const double travel_m = pending_.distance_m * mean_distance_scale();
    const double heading_rad = pose.yaw_rad + 0.5 * turn_rad;
    pose.x_m += travel_m * std::cos(heading_rad);
    pose.y_m += travel_m * std::sin(heading_rad);
    pose.yaw_rad = wrap_angle(pose.yaw_rad + turn_rad);
  }
  return pose;
}

template <typename X, typename Y>
ParticleFilter::PositionStats ParticleFilter::weighted_stats(const X& x_at,
                                                             const Y& y_at) const noexcept {
  PositionStats stats;
  for (std::size_t i = 0; i < count_; ++i) {
    stats.mean_x_m += weight_[i] * x_at(i);
    stats.mean_y_m += weight_[i] * y_at(i);
  }
  double variance = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    const double dx = x_at(i) - stats.mean_x_m;
    const double dy = y_at(i) - stats.mean_y_m;
    variance += weight_[i] * (dx * dx + dy * dy);
  }
  stats.spread_m = std::sqrt(variance);
  return stats;
}

ParticleFilter::PositionStats ParticleFilter::expected_fix_stats(
    const GpsObservation& fix) const noexcept {
  return weighted_stats(
      [&](std::size_t i) { return antenna_x_m(i, fix) + gps_slow_x_m_[i] + gps_fast_x_m_[i]; },
      [&](std::size_t i) { return antenna_y_m(i, fix) + gps_slow_y_m_[i] + gps_fast_y_m_[i]; });
}

double ParticleFilter::heading_spread_rad() const noexcept {
  double cos_sum = 0.0;
  double sin_sum = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    cos_sum += weight_[i] * cos_yaw_[i];
    sin_sum += weight_[i] * sin_yaw_[i];
  }
  const double resultant = std::hypot(cos_sum, sin_sum);
  return resultant > 0.0 ? std::sqrt(-2.0 * std::log(std::min(resultant, 1.0)))
                         : std::numeric_limits<double>::infinity();
}

double ParticleFilter::mean_distance_scale() const noexcept {
  double mean = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    mean += weight_[i] * scale_[i];
  }
  return mean;
}

double ParticleFilter::mean_yaw_rate_bias_radps() const noexcept {
  double mean = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    mean += weight_[i] * yaw_rate_bias_radps_[i];
  }
  return mean;
}

}  // namespace blockmap::localize
