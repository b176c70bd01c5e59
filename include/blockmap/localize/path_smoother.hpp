// The whole run's path as one least-squares problem: the first piece of the rigid map
// (docs/localize.md, The whole path at once).
//
// Why. The particle filter's smoothed path follows the receiver's slow error, which wanders by
// a metre over a minute: each building is drawn where the path was off while the robot passed
// it, each by its own amount (docs/buildings.md). A path whose shape comes from the robot's
// own motion (the scan matcher's, or the filter's calibrated dead reckoning) and whose place
// comes from every fix of the run at once is off by the receiver's error averaged over the
// run, the same for every building: about half a metre on benning instead of a metre, and
// nothing a mapper fed that receiver can remove (scripts/gps-bound).
//
// The problem. One keyframe per fix (and one per keyframe_spacing_m of motion without fixes),
// each with the state (x, y, yaw, bx, by): the robot's pose in the local frame and the
// receiver's slow error at that time. Three kinds of terms, each a Gaussian:
//  - motion: between consecutive keyframes, the odometry's relative motion in the first one's
//    frame, its variance growing with the distance driven (along and across the way apart)
//    and with the distance and time for the turn;
//  - the receiver's slow error: a first-order Gauss-Markov process (stationary sigma
//    bias_sigma_m, time constant bias_time_s), the model the filter and the simulator use;
//  - fixes: position plus slow error equals the fix, with the fast part's variance. A
//    carrier-phase (RTK) fix has no slow error of the receiver's kind (the base station's
//    corrections take it out): position equals the fix, to centimetres.
//  - ties between passes: a wall seen on one pass and again minutes later is one wall, so
//    the later look moved by its keyframe's correction lies on the earlier look moved by
//    its own (offset along the normal, and the turn). The caller pairs the looks (tie()).
// Motion, receiver and fix terms link a keyframe to itself or to the next one: the normal
// equations are block tridiagonal (5 x 5 blocks), and a block Cholesky sweep along the path
// solves them, O(keyframes), in fixed-size Eigen blocks. A tie links keyframes far apart and
// breaks the band: with ties, conjugate gradients solve the whole system, preconditioned by
// the band's factors. A tie adds rank 2 to the band, so about two steps a tie reach the answer.
//
// Fixed size: every array is taken from the arena at init. When the keyframes fill, every
// other one is merged into the one before it (its fix moved there by the path as solved, its
// weight added), so a run of any length keeps the whole path at half the resolution (counted:
// thinnings). add() and solve() allocate nothing.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/localize/scan_matcher.hpp"

namespace blockmap::localize {

struct PathSmootherConfig {
  std::size_t max_keyframes = 2048;  // at 4 Hz fixes, 8.5 minutes before the first thinning
  // A keyframe every this much motion when no fix comes (an outage, a receiver without fix).
  double keyframe_spacing_m = 1.0;
  // The odometry's relative motion: the variance per metre driven, along and across the way,
  // and of the turn per metre and per second (a gyroscope's bias left after calibration).
  double along_sigma_per_sqrt_m = 0.02;
  double across_sigma_per_sqrt_m = 0.01;
  double yaw_sigma_per_sqrt_m = 0.002;
  double yaw_sigma_per_sqrt_s = 0.001;
  // The same across the way and in the turn for the motion scans were matched over, once the
  // caller says how much the odometry carried alone (note_dead_reckoning(); without, all of
  // the motion is the odometry's). A scan matcher holds those to its map far tighter than
  // dead reckoning does, and its turn has no gyroscope bias: yaw_sigma_per_sqrt_s then
  // counts over the dead-reckoned time only.
  double matched_across_sigma_per_sqrt_m = 0.01;
  double matched_yaw_sigma_per_sqrt_m = 0.002;
  // The gyroscope's bias before any scan was matched (0: calibrated): nothing has taught it
  // yet, and the turn the odometry carries alone till then takes this much more variance
  // per second: sigma^2 times the time such a bias lasts (a Gauss-Markov bias's turn).
  double unlearnt_yaw_rate_bias_sigma_radps = 0.0;
  double unlearnt_yaw_rate_bias_time_s = 20.0;
  // The receiver: the slow part of its error per axis and how long it lasts, and the fast
  // part per fix (multipath and noise) for a fix of sigma 1 (add()'s fix_sigma_scale).
  double bias_sigma_m = 1.2;
  double bias_time_s = 60.0;
  double fix_sigma_m = 6.4;
  // Carrier-phase fixes, per fix (their errors are correlated over seconds too).
  double rtk_fixed_sigma_m = 0.05;
  double rtk_float_sigma_m = 0.5;
  // Gauss-Newton steps per solve(); each starts from the last solution.
  std::uint32_t iterations = 3;
  // Ties between passes: the most kept (when full, the two most alike of the kept and the new
  // one hold nearly the same, and one of them gives way: see tie()), how far
  // the two looks may disagree after the corrections (sigmas of the offset along the wall's
  // normal and of its turn), and beyond how many sigmas a tie pulls no harder (Huber: one
  // tie does not outweigh a pass's fixes). Pairing the looks is the caller's: a wrong pair
  // within the receiver's slow error can still move a pass by about that error, so the
  // caller's gate (the mapper's: 2 m, 5 degrees, walls that overlap) keeps pairs plausible.
  std::size_t max_ties = 256;
  double tie_offset_sigma_m = 0.3;
  double tie_angle_sigma_deg = 1.5;
  double tie_huber_sigmas = 3.0;
  // A tie whose walls, moved by the solved path, turn apart by more than this is left out of
  // that Gauss-Newton step: its looks were not drawn with the poses of those keyframes.
  double tie_gate_deg = 5.0;
  // Conjugate-gradient steps per Gauss-Newton step when there are ties.
  std::uint32_t cg_iterations = 64;
  // Loop closures: the most kept (when full, every other one of the older half goes), and
  // beyond how many sigmas (Mahalanobis) one pulls no harder.
  std::size_t max_closures = 256;
  double closure_huber_sigmas = 3.0;
};

// A wall as one pass drew it (in the caller's drawn map): its horizontal unit normal, a point
// on it, and a time at which a keyframe near it drew it.
struct WallLook {
  TimestampNs stamp_ns = 0;
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();
  Eigen::Vector2d point_m = Eigen::Vector2d::Zero();
};

// A loop closure (LoopCloser): `later`'s pose in `earlier`'s frame as the lasers matched
// them, both given as the odometry poses of their times (what add() was given then), with
// the match's information on (x, y, yaw).
struct LoopClosure {
  Pose2 earlier;
  Pose2 later;
  Eigen::Vector3d measured = Eigen::Vector3d::Zero();
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
};

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const PathSmootherConfig& config);

struct PathSmootherCounters {
  std::uint64_t keyframes_added = 0;
  std::uint64_t fixes = 0;
  std::uint64_t placings = 0;   // positions from a prior map (place())
  std::uint64_t thinnings = 0;  // the keyframes filled and every other one was merged
  std::uint64_t solves = 0;
  std::uint64_t refused = 0;           // add() with a time before the last keyframe's
  std::uint64_t ties = 0;              // ties between passes added
  std::uint64_t ties_refreshed = 0;    // a later look of the same pass took a tie's place
  std::uint64_t ties_dropped = 0;      // the ties were full and the new one was the spare
  std::uint64_t ties_replaced = 0;     // the ties were full and a kept one gave the new its place
  std::uint64_t cg_steps = 0;          // conjugate-gradient steps, all solves
  std::uint64_t closures = 0;          // loop closures added
  std::uint64_t closures_dropped = 0;  // the closures were full: kept ones that went
};

class PathSmoother {
 public:
  // Floors on the motion's variances: a robot standing still for a minute of fixes is held
  // still, but not so rigidly that the normal equations lose their digits.
  static constexpr double kMinMotionVarianceM2 = 1e-6;
  static constexpr double kMinTurnVarianceRad2 = 1e-8;
  // The receiver's error between two fixes of one epoch is the same error (1 - a^2 floored).
  static constexpr double kMinBiasDecay = 1e-6;

  void init(Arena& arena, const PathSmootherConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const PathSmootherConfig& config) noexcept;
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

  // The odometry's pose at odometry.stamp_ns (a frame that drifts but never jumps: the scan
  // matcher's matched pose or the filter's dead reckoning), with the GPS fix of that time in
  // the local frame when there is one (east, north; for a code fix, fix_sigma_scale
  // multiplies the configured sigma, an HDOP's worth; a carrier-phase fix takes rtk_*_sigma_m
  // as it is). A keyframe is made for every fix, and for every keyframe_spacing_m of motion
  // without one. Times must not go back (refused, counted).
  void add(const Pose2& odometry, const std::optional<Eigen::Vector2d>& fix_m,
           double fix_sigma_scale = 1.0, GpsCorrection correction = GpsCorrection::kNone) noexcept {
    add(odometry, odometry, fix_m, fix_sigma_scale, correction);
  }
  // The same, with the pose the caller drew its map with at that time (kept with the
  // keyframe: correction() says how to move what was drawn then).
  void add(const Pose2& odometry, const Pose2& drawn, const std::optional<Eigen::Vector2d>& fix_m,
           double fix_sigma_scale = 1.0, GpsCorrection correction = GpsCorrection::kNone) noexcept;
  // A keyframe at `odometry` whose position a prior map gave (MapLocalizer): position equals
  // `position_m` with `information` (east, north; per square metre: zero along a bare
  // street), and no receiver's slow error (the map's offset instead, when carried:
  // carry_map_offset()).
  void place(const Pose2& odometry, const Pose2& drawn, const Eigen::Vector2d& position_m,
             const Eigen::Matrix2d& information) noexcept;
  // The robot started at a known pose: the first keyframe is held where it was drawn, within
  // these sigmas. Without it a path placed only by a prior map's walls is free to slide along
  // a street whose walls pin one direction, or to turn about the stretch they pin.
  void hold_first(double sigma_m, double yaw_sigma_rad) noexcept;
  [[nodiscard]] bool holds_first() const noexcept { return first_information_[0] > 0.0; }
  // A path held at its start and placed on a prior map: the map's own frame may sit off the
  // start's (an earlier run's receiver put it there), so the placings share the slow-error
  // states, which take the map's offset instead of a receiver's (this stationary sigma and
  // time constant). Without it the placings bend the path between its start and the map.
  void carry_map_offset(double sigma_m, double time_s) noexcept;
  [[nodiscard]] bool carries_map_offset() const noexcept { return placings_carry_offset_; }
  // The slow error's states at the keyframe nearest `odometry` (east, north): the receiver's
  // or, carried, the prior map's offset.
  [[nodiscard]] Eigen::Vector2d slow_error(const Pose2& odometry) const noexcept;

  // Of the motion from the last keyframe to the next one, this much (and this long) the
  // odometry carried alone (no scan was matched over it), and this long scans were matched:
  // the first is weighed with the odometry's sigmas, the rest with the matched ones, and only
  // its time with the turn's per second (and, before any scan was matched, the bias's).
  void note_dead_reckoning(double distance_m, double duration_s, double matched_s) noexcept;

  // The wall `key` (the caller's name for it) that `earlier` saw is the wall `later` sees,
  // on another pass. A tie of the same key whose later look is of this pass (less than
  // kSamePassNs before this one) takes this look instead: the wall grows as the robot passes.
  // When the ties are full, of the kept ones and this one the two most alike (tie_likeness_ns)
  // hold nearly the same stretches of path to each other: the older of the two goes, or this
  // one if it is of the two. Dropping every new tie instead would leave the later passes of a
  // long run untied, however far they drift; this keeps the ties spread over the run.
  // Returns whether the tie is kept (false: it was the spare one, or there are no keyframes).
  static constexpr TimestampNs kSamePassNs = 20 * kNanosecondsPerSecond;
  bool tie(std::uint32_t key, const WallLook& earlier, const WallLook& later) noexcept;
  [[nodiscard]] std::size_t tie_count() const noexcept { return tie_count_; }

  // A loop closure between two times of the path; its pull is Huber's beyond
  // closure_huber_sigmas. When full, every other one of the older half goes first.
  void close_loop(const LoopClosure& closure) noexcept;
  [[nodiscard]] std::size_t closure_count() const noexcept { return closure_count_; }

  // Gauss-Newton over the whole path, from the last solution (new keyframes start where the
  // odometry puts them from the keyframe before). Cost: O(keyframes) per iteration without
  // ties; with them, O(keyframes) per conjugate-gradient step.
  void solve() noexcept;

  [[nodiscard]] std::size_t keyframe_count() const noexcept { return count_; }
  // The solved pose at keyframe i (0: the oldest).
  [[nodiscard]] Pose2 pose(std::size_t i) const noexcept;
  // The solved pose at stamp_ns: the keyframe at or before it, moved by the odometry to the
  // next one's time in proportion (odometry poses in between are not kept). Before the first
  // keyframe, the first; after the last, the last.
  [[nodiscard]] Pose2 pose_at(TimestampNs stamp_ns) const noexcept;
  // Keyframe i's drawn pose (as given), and the rigid motion that takes it to the solved one:
  // what moves a part of the map drawn at that time to where the solved path puts it.
  // The solved pose at a time whose odometry pose the caller has: the nearest keyframe's,
  // moved by the odometry from it (keyframes between fixes are not every scan's).
  [[nodiscard]] Pose2 solved_pose(const Pose2& odometry) const noexcept;
  [[nodiscard]] const Pose2& drawn(std::size_t i) const noexcept;
  [[nodiscard]] const Pose2& odometry(std::size_t i) const noexcept;
  [[nodiscard]] PlanarCorrection correction(std::size_t i) const noexcept;
  [[nodiscard]] const PathSmootherCounters& counters() const noexcept { return counters_; }

 private:
  // Fixes merged into a keyframe: their weighted mean and the sum of their 1 / sigma^2.
  struct FixMean {
    double east_m = 0.0;
    double north_m = 0.0;
    double weight = 0.0;  // 0: none
    void merge(double east, double north, double more_weight) noexcept;
  };
  // A prior map's placings merged into a keyframe, as their normal equations: the summed
  // information (xx, xy, yy) and the information times the placed position.
  struct Placings {
    double information[3] = {};
    double moment[2] = {};
    void merge(const Eigen::Vector2d& position_m, const Eigen::Matrix2d& more) noexcept;
    // Another keyframe's, whose placed positions move by -by_m to this one.
    void merge_moved(const Placings& other, const Eigen::Vector2d& by_m) noexcept;
  };
  struct Keyframe {
    Pose2 odometry;                // as given
    Pose2 drawn;                   // as given
    FixMean code_fixes;            // position + slow error = fix
    FixMean carrier_fixes;         // position = fix (RTK)
    Placings placings;             // position (+ slow error, carried) = a prior map's placings
    double state[5] = {};          // x, y, yaw, bx, by as solved
    double dead_reckoned_m = 0.0;  // of the motion from the keyframe before: odometry alone
    double dead_reckoned_s = 0.0;
    double unlearnt_turn_variance_rad2 = 0.0;  // the gyroscope's bias over dead_reckoned_s
  };
  // The normal equations' blocks at keyframe i: the diagonal, the one coupling it to i + 1,
  // and the gradient; the band's factors overwrite the first two (L with S = L L', and
  // X = S^-1 U), and the negated gradient is conjugate gradients' residual. `direction` and
  // `work` are their other vectors: `work` holds the preconditioned residual, then the system
  // times the direction, whose lives do not overlap (70 doubles a keyframe, not 80: the
  // rmp_tim robot's capacities fit the 64 MiB budget with it).
  struct Blocks {
    double diagonal[25] = {};
    double upper[25] = {};
    double gradient[5] = {};
    double step[5] = {};
    double direction[5] = {};
    double work[5] = {};
  };
  using Vector5Member = double (Blocks::*)[5];
  // A tie and its terms at the last linearization: the keyframes of its looks, the
  // residual's (offset, turn) Jacobians on their (x, y, yaw), and the weights.
  struct Tie {
    std::uint32_t key = 0;
    WallLook earlier;
    WallLook later;
    std::size_t a = 0;
    std::size_t b = 0;
    double jacobian_a[6] = {};
    double jacobian_b[6] = {};
    double residual[2] = {};
    double weight[2] = {};
  };

  // A closure and its terms at the last linearization: the keyframes nearest its ends, the
  // residual's Jacobians on their (x, y, yaw) (3 x 3, row-major), and its weight (the
  // information, Huber's share taken).
  struct Closure {
    LoopClosure closure;
    std::size_t a = 0;
    std::size_t b = 0;
    double jacobian_a[9] = {};
    double jacobian_b[9] = {};
    double residual[3] = {};
    double weight[9] = {};
  };

  void append(const Pose2& odometry, const Pose2& drawn) noexcept;
  // Whether `odometry` is older than the last keyframe (refused, counted).
  bool refuses(const Pose2& odometry) noexcept;
  // The keyframe at `odometry`'s time (made when the last is older) for a fix or a placing at
  // `position_m`; the first of them moves the whole path there.
  Keyframe& keyframe_placed_at(const Pose2& odometry, const Pose2& drawn,
                               const Eigen::Vector2d& position_m) noexcept;
  void thin() noexcept;
  void accumulate_motion(std::size_t i) noexcept;
  void accumulate_receiver(std::size_t i) noexcept;
  void accumulate_fix(std::size_t i) noexcept;
  void accumulate_fix(std::size_t i, const FixMean& fixes, bool slow_error) noexcept;
  void accumulate_placings(std::size_t i) noexcept;
  void accumulate_first_hold() noexcept;
  // How alike two ties are: the longer of the times between their earlier looks and between
  // their later looks (ties that close hold the same two stretches of path to each other), or
  // the most there is when their walls are not parallel (a corner's two walls hold the path
  // along both axes: neither is spare).
  [[nodiscard]] static TimestampNs tie_likeness_ns(const Tie& p, const Tie& q) noexcept;
  // Full: the slot the new tie takes, or ties_.size() when it is the spare one. O(ties^2),
  // only when full.
  [[nodiscard]] std::size_t spare_tie_slot(const Tie& candidate) const noexcept;
  void linearize_tie(Tie& tie) const noexcept;
  void accumulate_tie_gradient(const Tie& tie) noexcept;
  void linearize_closure(Closure& closure) const noexcept;
  void accumulate_closure_gradient(const Closure& closure) noexcept;
  void add_closures_times(Vector5Member in, Vector5Member out) noexcept;
  [[nodiscard]] std::size_t keyframe_nearest(TimestampNs stamp_ns) const noexcept;
  // The band's block Cholesky in place, then band^-1 of `in` into `out`, and band times `in`.
  [[nodiscard]] bool factor_band() noexcept;
  void solve_band(Vector5Member in, Vector5Member out) noexcept;
  void multiply_band(Vector5Member in, Vector5Member out) noexcept;
  void add_ties_times(Vector5Member in, Vector5Member out) noexcept;
  [[nodiscard]] double dot(Vector5Member a, Vector5Member b) const noexcept;
  // The Gauss-Newton step into each block's `step`: the band's sweep without ties,
  // preconditioned conjugate gradients with them.
  [[nodiscard]] bool solve_step() noexcept;

  PathSmootherConfig config_;
  std::span<Keyframe> keyframes_;
  std::span<Blocks> blocks_;
  std::span<Tie> ties_;
  std::span<Closure> closures_;
  std::size_t count_ = 0;
  std::size_t tie_count_ = 0;
  std::size_t closure_count_ = 0;
  double dead_reckoned_m_ = 0.0;  // noted since the last keyframe
  double dead_reckoned_s_ = 0.0;
  double unlearnt_turn_variance_rad2_ = 0.0;
  bool matched_any_ = false;            // a scan was matched: the gyroscope's bias is learnt
  bool noted_dead_reckoning_ = false;   // the caller tells matched motion from odometry's
  double first_information_[2] = {};    // the first keyframe's hold: position, yaw (0: none)
  bool placings_carry_offset_ = false;  // placings share the slow error (carry_map_offset())
  PathSmootherCounters counters_;
};

}  // namespace blockmap::localize
