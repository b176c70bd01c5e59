// Where the robot is (the seed's section II): a particle filter over (x, y, yaw) in the local
// ENU frame that moves its particles with wheel odometry and the gyroscope's yaw rate, and
// weighs them by their distance to each GPS fix.
//
// Changes from the paper, each for a reason:
//  - Fixed size. The particle count and the history are capacities taken from the arena at
//    init; predict() and update() allocate nothing.
//  - Bounded history instead of the complete one. Every history_interval_s, the particles'
//    poses and the index of each one's ancestor at the previous history step go into a ring
//    of history_steps. The survivors' ancestries give a fixed-lag smoothed path. A step that
//    leaves the ring is final: its smoothed pose is the weighted mean of the current
//    particles' ancestors at that step.
//  - Each particle carries its own distance scale and yaw-rate bias. Tyre pressure makes
//    the wheels report 1-2 % too much or too little, and the gyroscope drifts; particles with
//    the wrong ones drift away from GPS and are not resampled.
//  - The fix's reported quality sets its weight: sigma = user range error x HDOP. DGPS and RTK
//    fixes count more.
//  - The receiver's error is not white. Its slow part (orbits, clocks, the atmosphere) and its
//    fast part (multipath) are states of each particle, estimated by a small Kalman filter
//    per particle (Rao-Blackwellized: the particles stay in x, y, yaw). Odometry tells them
//    apart from the motion.
//  - The paper's rule (particles farther than a distance from the fix are not resampled) is
//    kept. Recovery: a fix that no particle is near is an outlier and is left out. After
//    several such fixes in a row, GPS is believed and the particles start over around it.
//
// Noise comes from a table of Gaussian quantiles, indexed by a seeded generator: the same
// inputs and seed give the same trajectory, bit for bit.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/random.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/localize/localize_config.hpp"

namespace blockmap::localize {

// A planar pose in the local ENU frame: x east, y north, yaw counter-clockwise from east.
struct Pose2 {
  TimestampNs stamp_ns = 0;
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;
};

// What the receiver corrected its fix with (NMEA GGA's quality): the fix's error follows.
enum class GpsCorrection : std::uint8_t {
  kNone,          // a code fix alone: metres, user_range_error_m x HDOP
  kDifferential,  // DGPS or SBAS corrections: better than the HDOP says (dgps_sigma_factor)
  kRtkFloat,      // carrier phase, ambiguities not fixed: decimetres (rtk_float_sigma_m)
  kRtkFixed,      // carrier phase, ambiguities fixed: centimetres (rtk_fixed_sigma_m)
};

[[nodiscard]] constexpr bool carrier_phase(GpsCorrection correction) noexcept {
  return correction == GpsCorrection::kRtkFloat || correction == GpsCorrection::kRtkFixed;
}

// A GPS fix already in the local frame (hal converts geodetic coordinates): where the antenna
// was. The antenna's horizontal offset from the robot frame's origin, ahead along the robot's
// heading and to its left (its mount turned by the pitch and roll of the moment), makes each
// particle expect the fix from its own position and heading: a heading not yet known turns
// the offset differently for each particle.
struct GpsObservation {
  TimestampNs stamp_ns = 0;  // the fix's epoch on the run's clock
  double east_m = 0.0;
  double north_m = 0.0;
  double hdop = 1.0;
  GpsCorrection correction = GpsCorrection::kNone;
  double antenna_ahead_m = 0.0;
  double antenna_left_m = 0.0;
};

enum class GpsOutcome : std::uint8_t {
  kStarted,    // the first fix: the particles were spread around it
  kUsed,       // the particles were weighed by it
  kRejected,   // an outlier, left out
  kRecovered,  // too many outliers in a row: the particles started over around it
};

struct LocalizeCounters {
  std::uint64_t predictions = 0;
  std::uint64_t fixes_used = 0;
  std::uint64_t fixes_rejected = 0;
  std::uint64_t recoveries = 0;
  std::uint64_t resamplings = 0;
  std::uint64_t history_steps = 0;
  std::uint64_t final_poses_dropped = 0;  // finalized faster than drained
};

class ParticleFilter {
 public:
  void init(Arena& arena, const LocalizeConfig& config);
  // Arena bytes init() takes for `config`.
  [[nodiscard]] static std::size_t arena_bytes(const LocalizeConfig& config) noexcept;

  [[nodiscard]] bool started() const noexcept { return started_; }

  // Odometry since the last call: the base's fore/aft distance increment and the gyroscope's
  // yaw rate, at `stamp_ns`. Before the first fix only the time is kept.
  void predict(TimestampNs stamp_ns, double distance_m, double yaw_rate_radps) noexcept;
  // A GPS fix. Fixes must not be older than the last odometry (the pipeline orders them).
  GpsOutcome update(const GpsObservation& fix) noexcept;
  // A start without a fix, at a pose known otherwise (a robot without a receiver that starts
  // where its map says): the particles drawn around it by these sigmas, the odometry's scale
  // and gyroscope bias as at any start. Fixes that come later weigh them as usual.
  void start_at_pose(const Pose2& pose, double position_sigma_m, double yaw_sigma_rad) noexcept;

  // The weighted mean of the particles now (odometry not yet applied to them included).
  [[nodiscard]] Pose2 estimate() const noexcept;
  // The spread of the particles' headings: the circular standard deviation, sqrt(-2 ln R)
  // for the mean resultant length R of their weighted unit vectors (infinite for headings
  // spread evenly round, as at the start before the robot has moved).
  [[nodiscard]] double heading_spread_rad() const noexcept;
  // The mean distance scale and yaw-rate bias the particles carry.
  [[nodiscard]] double mean_distance_scale() const noexcept;
  [[nodiscard]] double mean_yaw_rate_bias_radps() const noexcept;

  // Poses that left the history window, oldest first, smoothed by the particles that
  // survived them; each is handed out once.
  std::size_t drain_final(std::span<Pose2> out) noexcept;
  // The smoothed poses of every step still in the window, oldest first (at the end of a run:
  // the rest of the trajectory). Returns how many were written.
  std::size_t smoothed_window(std::span<Pose2> out) const noexcept;
  // The pose at `stamp_ns` on the smoothed path, interpolated between history steps (and
  // towards the current estimate after the newest one); false outside the window.
  bool pose_at(TimestampNs stamp_ns, Pose2& out) const noexcept;

  [[nodiscard]] const LocalizeCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t particle_count() const noexcept { return count_; }
  [[nodiscard]] std::size_t history_size() const noexcept { return history_size_; }
  // The time of the newest odometry: pose_at() answers up to it.
  [[nodiscard]] TimestampNs last_stamp_ns() const noexcept { return last_stamp_ns_; }
  // The stamp of the newest history step (0 before the first).
  [[nodiscard]] TimestampNs newest_step_ns() const noexcept {
    return history_size_ == 0 ? 0 : history_stamps_[history_newest_];
  }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  struct HistoryEntry {
    float x_m = 0.0f;  // the local frame is at most a few kilometres across: millimetres
    float y_m = 0.0f;
    float yaw_rad = 0.0f;
    std::uint32_t parent = 0;  // the particle's index at the previous history step
  };

  struct PositionStats {
    double mean_x_m = 0.0;
    double mean_y_m = 0.0;
    double spread_m = 0.0;
  };
  // Of where the particles expect `fix`: the antenna's position plus their estimate of the
  // receiver's error.
  [[nodiscard]] PositionStats expected_fix_stats(const GpsObservation& fix) const noexcept;
  // Particle i's antenna (x, y) at `fix`.
  [[nodiscard]] double antenna_x_m(std::size_t i, const GpsObservation& fix) const noexcept {
    return x_m_[i] + cos_yaw_[i] * fix.antenna_ahead_m - sin_yaw_[i] * fix.antenna_left_m;
  }
  [[nodiscard]] double antenna_y_m(std::size_t i, const GpsObservation& fix) const noexcept {
    return y_m_[i] + sin_yaw_[i] * fix.antenna_ahead_m + cos_yaw_[i] * fix.antenna_left_m;
  }
  // The weighted mean and spread of a position per particle.
  template <typename X, typename Y>
  [[nodiscard]] PositionStats weighted_stats(const X& x_at, const Y& y_at) const noexcept;
  // A fix's error variances per axis, in its three parts.
  struct FixError {
    double slow_variance_m2 = 0.0;
    double fast_variance_m2 = 0.0;
    double white_variance_m2 = 0.0;
  };
  // The covariance of every particle's (slow, fast) error estimate, per axis.
  struct GpsErrorCovariance {
    double slow_slow = 0.0;
    double slow_fast = 0.0;
    double fast_fast = 0.0;
  };
  [[nodiscard]] double gaussian() noexcept;
  // Odometry waits in a batch (pending_) and moves the particles once per batch: the motion
  // loop is most of the filter's cost, and 100 Hz of base samples need not run it 100 times a
  // second. A batch ends before a fix, before a history step and when it is long.
  void accumulate_motion(double dt_s, double distance_m, double yaw_rate_radps) noexcept;
  void apply_motion() noexcept;
  void start_at(const GpsObservation& fix, double sigma_m, bool keep_heading) noexcept;
  [[nodiscard]] double fix_sigma_m(const GpsObservation& fix) const noexcept;
  // How far around a fix the particles start: initial_position_sigma_m, or three of the fix's
  // sigmas when that is less (a centimetre fix with particles spread over metres would leave
  // none of them near it).
  [[nodiscard]] double start_spread_m(const GpsObservation& fix) const noexcept;
  [[nodiscard]] FixError fix_error(const GpsObservation& fix) const noexcept;
  void advance_gps_error(double dt_s, const FixError& error) noexcept;
  [[nodiscard]] double fix_innovation_variance_m2(const FixError& error) const noexcept;
  [[nodiscard]] bool is_outlier(const GpsObservation& fix, const FixError& error) const noexcept;
  void weigh(const GpsObservation& fix, const FixError& error) noexcept;
  // After a resampling on a carrier-phase fix: each particle's heading and gyroscope bias
  // jittered (rtk_*_roughening). A centimetre fix leaves few particles with weight, and their
  // headings and biases are all the filter keeps; the random walks of the action model are
  // too slow to find the truth again, so a wrong bias turns the heading degrees off while the
  // fixes hold the position. Jittered, the particles that drift least are kept at the next
  // fix, and the heading and bias follow.
  void roughen() noexcept;
  void normalize_weights() noexcept;
  [[nodiscard]] double effective_particles() const noexcept;
  void resample() noexcept;
  void push_history(TimestampNs stamp_ns) noexcept;
  void finalize_oldest() noexcept;
  // Lineages: the distinct history entries the current particles descend from at one step,
  // each with the summed weight of its descendants (in trace_ and trace_weight_).
  void start_lineages() const noexcept;
  void next_lineage_generation() const noexcept;
  void add_to_lineage(std::uint32_t index, double weight) const noexcept;
  void step_lineages_back(std::size_t age) const noexcept;
  [[nodiscard]] Pose2 lineage_pose(std::size_t age) const noexcept;
  // The smoothed pose `age` steps back from the newest.
  [[nodiscard]] Pose2 smoothed_at(std::size_t age) const noexcept;
  [[nodiscard]] std::size_t slot_of_age(std::size_t age) const noexcept;

  LocalizeConfig config_;
  Random random_{1, "localize.particles"};
  std::span<float> gaussian_table_;  // quantiles of N(0, 1)
  std::uint64_t random_bits_ = 0;
  std::uint32_t random_bits_left_ = 0;

  // The particles, one array per quantity.
  std::size_t count_ = 0;
  std::span<double> x_m_;
  std::span<double> y_m_;
  std::span<double> yaw_rad_;
  std::span<double> cos_yaw_;  // of yaw_rad_, kept by rotation in predict()
  std::span<double> sin_yaw_;
  std::span<double> scale_;
  std::span<double> yaw_rate_bias_radps_;
  // Each particle's estimate of the receiver's error, slow and fast parts (the means of its
  // Kalman filter; the covariance, the same for all, is gps_covariance_).
  std::span<double> gps_slow_x_m_;
  std::span<double> gps_slow_y_m_;
  std::span<double> gps_fast_x_m_;
  std::span<double> gps_fast_y_m_;
  GpsErrorCovariance gps_covariance_;
  TimestampNs gps_error_stamp_ns_ = 0;
  std::span<double> weight_;
  std::span<std::uint32_t> ancestor_;  // each particle's index at the newest history step
  // Resampling's scratch: the chosen indices and a second copy of every quantity.
  std::span<std::uint32_t> chosen_;
  std::span<double> scratch_;

  // The history ring: history_steps x particle_count entries, and each step's stamp.
  std::span<HistoryEntry> history_;
  std::span<TimestampNs> history_stamps_;
  std::span<std::uint8_t> history_identity_;  // 1: no resampling before this step
  bool resampled_since_push_ = false;
  std::size_t history_newest_ = 0;
  std::size_t history_size_ = 0;
  // Lineage scratch (the smoothing queries are const: these are working space, not state).
  std::span<std::uint32_t> trace_;         // distinct entry indices
  std::span<double> trace_weight_;         // their descendants' summed weights
  std::span<std::uint32_t> lineage_slot_;  // per entry index: its place in trace_
  std::span<std::uint32_t> lineage_seen_;  // per entry index: the generation that placed it
  // pose_at() after the newest history step: its two ends, valid while version_ holds.
  [[nodiscard]] static Pose2 interpolate(const Pose2& earlier, const Pose2& later,
                                         TimestampNs stamp_ns) noexcept;
  std::uint64_t version_ = 0;  // counts predict() and update() calls
  mutable std::uint64_t newest_span_version_ = ~std::uint64_t{0};
  mutable Pose2 newest_span_earlier_;
  mutable Pose2 newest_span_later_;
  mutable std::size_t lineage_count_ = 0;
  mutable std::uint32_t lineage_generation_ = 0;
  std::span<Pose2> final_;  // finalized poses waiting to be drained (a ring)
  std::size_t final_first_ = 0;
  std::size_t final_count_ = 0;

  struct PendingMotion {
    double distance_m = 0.0;  // summed fore/aft distance
    double turn_rad = 0.0;    // summed gyroscope turn (rate x time)
    double dt_s = 0.0;
    double distance_variance_m2 = 0.0;  // the steps' noise variances, summed
    double yaw_variance_rad2 = 0.0;
    double scale_variance = 0.0;
    double bias_variance_radps2 = 0.0;
    std::uint32_t steps = 0;
  };
  PendingMotion pending_;

  bool started_ = false;
  bool have_stamp_ = false;
  TimestampNs last_stamp_ns_ = 0;
  TimestampNs next_history_ns_ = 0;
  std::uint32_t rejected_in_a_row_ = 0;
  LocalizeCounters counters_;
};

}  // namespace blockmap::localize
