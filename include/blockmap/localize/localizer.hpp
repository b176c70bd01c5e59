// The localizer of the pipeline: the particle filter fed with what the devices report. It
// turns the Segway's integrated odometry into distance increments (and notices when the base
// resets its integrators), takes the yaw rate from the base's gyroscope, and completes the
// filter's planar poses into 3D ones with the base's own pitch and roll (the seed: the RMP
// "pitches considerably", which the scan projector must undo) and a height from GPS.
//
// The receiver reports where its antenna is; the filter tracks the robot frame's origin. Each
// fix carries the antenna's mount turned by the base's pitch and roll of the moment, and each
// particle expects the fix there from its own position and heading: a mast-top antenna on the
// pitching RMP swings a decimetre fore and aft, nothing against a code fix's 2 m but several
// times an RTK fix's error.
//
// Height: the filter is planar. z is the antenna's height in the local frame less its mount's.
// A code receiver's height wanders metres within a minute, and the RMP's pitch is its balance,
// not the street's grade: with code fixes the map is level at the first fix's height (heights
// are the street's under the robot), unless level_with_code_fixes is off and they are
// low-passed over height_smoothing_s. A carrier-phase (RTK) fix's height is good to
// centimetres and is followed within rtk_height_smoothing_s, so that kerbs and slopes come
// out where they are.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/localize/localize_config.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/msg/odometry.hpp"

namespace blockmap::localize {

// A pose of the robot frame in the local ENU frame (the columns of trajectory.csv).
struct Pose3 {
  TimestampNs stamp_ns = 0;
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  double roll_rad = 0.0;
  double pitch_rad = 0.0;  // positive nose down, as the RMP reports it
  double yaw_rad = 0.0;
};

// The rotation of the robot frame into the local frame at an attitude: Rz(yaw) Ry(pitch)
// Rx(roll), positive pitch nose down (the RMP's sign).
[[nodiscard]] Eigen::Matrix3d attitude_rotation(double roll_rad, double pitch_rad,
                                                double yaw_rad) noexcept;

struct LocalizerConfig {
  LocalizeConfig filter;
  // The GPS antenna in the robot frame (x forward, y left, z up), metres.
  Eigen::Vector3d antenna_m = Eigen::Vector3d(0.0, 0.0, 1.3);
  bool level_with_code_fixes = true;
  double height_smoothing_s = 120.0;
  double rtk_height_smoothing_s = 1.0;
  // A fore/aft increment faster than this is the base resetting its integrators (power
  // cycle, a reset command), not motion: it is skipped and counted.
  double max_speed_mps = 10.0;
  // The mapper's poses (map_pose_at): odometry, with the filter's distance scale and gyro
  // bias, drawn toward the filter's estimate over map_pose_smoothing_s. The estimate moves
  // 0.1-0.9 m at a fix (4 Hz), and scans drawn at it smear every wall by as much. A map pose
  // farther than the snap limits from the estimate moves to it at once (the start, a
  // recovery).
  double map_pose_smoothing_s = 5.0;
  // While carrier-phase (RTK) fixes hold the estimate to centimetres, its steps at a fix are
  // centimetres too, and the map pose closes its gap over this instead.
  double rtk_map_pose_smoothing_s = 0.5;
  double map_pose_snap_m = 3.0;
  double map_pose_snap_rad = 0.35;  // 20 deg
  // With carrier-phase fixes, the map poses start once the particles' headings agree this
  // closely (ParticleFilter::heading_spread_rad): before, a robot that has not yet moved far
  // enough for its fixes to show its heading would draw its scans turned anywhere, and a
  // centimetre map keeps the wall they make. Code fixes take several seconds to show the
  // heading and put the map metres off anyway: their map starts at once, as it did
  // (docs/localize.md, RTK receivers).
  double map_pose_start_heading_spread_rad = 0.26;  // 15 deg
  // Map poses kept, one per base sample: how far back map_pose_at() reaches (10 s at 100 Hz).
  std::size_t map_pose_capacity = 1024;
  // A robot without a receiver starts at a pose known otherwise (replay --start-pose): the
  // filter starts there at the first odometry, not at a first fix.
  bool start_at_known_pose = false;
  Pose2 start_pose;  // its stamp is the first odometry's
  double start_position_sigma_m = 0.05;
  double start_yaw_sigma_rad = 0.005;
  // 0: the map pose is drawn toward the estimate as it is now. L > 0: the map pose runs L
  // seconds behind the newest base sample and is drawn toward the smoothed path at its own
  // time (the pose the fixes of the following L seconds agree on), every history step. The
  // forward estimate's heading wanders by degrees between fixes a few seconds apart, and
  // scans drawn with it bend the walls; the smoothed path's does not (docs/mapper.md,
  // Accuracy). The price is L seconds of delay before a scan can be drawn. L must stay
  // inside the filter's window (history_steps x history_interval_s) with 2 s to spare.
  double map_pose_lag_s = 0.0;
  // Base samples waiting for their lagged map pose (L seconds at the base's rate).
  std::size_t map_pose_lag_samples = 4096;
};

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const LocalizerConfig& config);

struct LocalizerCounters {
  std::uint64_t base_samples = 0;
  std::uint64_t odometry_jumps = 0;  // integrator resets skipped
  std::uint64_t stale_samples = 0;   // older than the last one, left out
  std::uint64_t map_pose_snaps = 0;  // map poses moved to the estimate at once
  std::uint64_t lag_forced = 0;      // base samples drawn early: map_pose_lag_samples was full
};

class Localizer {
 public:
  void init(Arena& arena, const LocalizerConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const LocalizerConfig& config) noexcept;

  // One status group of the base: its odometry and IMU samples (the same stamp).
  void on_base(const msg::OdometrySample& odometry, const msg::ImuSample& imu) noexcept;
  // A GPS fix of the antenna in the local frame; up_m is the antenna's height in that frame.
  GpsOutcome on_fix(const GpsObservation& fix, double up_m) noexcept;
  // The last fix on_fix() had, moved from the antenna to the robot frame's origin by the
  // filter's heading now (right after on_fix(), the heading after that fix).
  [[nodiscard]] GpsObservation last_robot_fix() const noexcept;
  // Whether carrier-phase fixes hold the pose at stamp_ns: the filter used one at most
  // kCarrierPhaseHoldNs before it and no code fix since. The receiver drops to code fixes
  // under tall buildings; then the scan matcher holds the map rigid again.
  static constexpr TimestampNs kCarrierPhaseHoldNs = 2 * kNanosecondsPerSecond;
  [[nodiscard]] bool carrier_phase_holds(TimestampNs stamp_ns) const noexcept;

  // As the filter's: poses that left the window (each once), the rest of the window, the
  // pose at a time inside it; with height, pitch and roll.
  std::size_t drain_final(std::span<Pose3> out) noexcept;
  std::size_t smoothed_window(std::span<Pose3> out) const noexcept;
  bool pose_at(TimestampNs stamp_ns, Pose3& out) const noexcept;
  // The pose to draw a scan with: smooth from one base sample to the next (odometry between
  // fixes), near the filter's estimate over seconds, with the base's attitude of that sample.
  // False before the filter starts and outside the last map_pose_capacity base samples.
  // `odometry`, when given, is the odometry's own pose at the stamp: the wheels' distance and
  // the gyroscope's turn as the base reports them, uncalibrated, from the filter's first
  // estimate on, never drawn toward the filter (what the scans of a scan matcher move by
  // between two matches; the matcher learns the gyroscope's bias itself).
  bool map_pose_at(TimestampNs stamp_ns, Pose3& out, Pose2* odometry = nullptr) const noexcept;
  // At the end of the input: the lagged map pose goes on until it reaches until_ns or the
  // last base sample (the smoothed path is as good as it will get). A step at a time, as the
  // last scans need it: the map poses' ring holds map_pose_capacity of them.
  void flush_map_pose(TimestampNs until_ns) noexcept;
  // Whether the map pose jumped to the estimate (a snap) at a stamp in (after_ns, until_ns]:
  // by the stamps of the last few snaps, however far the localizer has run ahead of the scans.
  [[nodiscard]] bool map_pose_snapped_between(TimestampNs after_ns,
                                              TimestampNs until_ns) const noexcept;
  // The newest time map_pose_at() answers for: the last base sample, or with a lag, the last
  // one the lagged map pose has reached. False before there is any.
  bool map_pose_horizon(TimestampNs& out) const noexcept;

  [[nodiscard]] const ParticleFilter& filter() const noexcept { return filter_; }
  [[nodiscard]] const LocalizerCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  // What the filter does not estimate, kept at each of its history steps.
  struct Attitude {
    TimestampNs stamp_ns = 0;
    float z_m = 0.0f;
    float roll_rad = 0.0f;
    float pitch_rad = 0.0f;
  };
  // One base sample as the map pose needs it (kept for map_pose_lag_s when there is a lag).
  struct BaseMotion {
    TimestampNs stamp_ns = 0;
    double distance_m = 0.0;
    double yaw_rate_radps = 0.0;
    double z_m = 0.0;
    double roll_rad = 0.0;
    double pitch_rad = 0.0;
  };
  void record_if_stepped() noexcept;
  // The base samples whose lagged map pose is due (older than map_pose_lag_s), in order.
  void advance_lagged_map_pose(TimestampNs until_ns) noexcept;
  void advance_lagged_one() noexcept;
  // One base sample's motion for the map pose, and the share of the pending correction due.
  void advance_map_pose(const BaseMotion& motion) noexcept;
  // The gap from the map pose to `target` becomes the correction to make over
  // map_pose_smoothing_s (or is closed at once beyond the snap limits): after a fix toward
  // the estimate, with a lag toward the smoothed path at each history step.
  void pull_map_pose(const Pose2& target, const BaseMotion& motion) noexcept;
  void keep_map_pose(const BaseMotion& motion) noexcept;
  [[nodiscard]] Attitude attitude_at(TimestampNs stamp_ns) const noexcept;
  void follow_height(const GpsObservation& fix, double height_m) noexcept;
  [[nodiscard]] Pose3 completed(const Pose2& pose) const noexcept;

  LocalizerConfig config_;
  ParticleFilter filter_;
  LocalizerCounters counters_;
  bool have_base_ = false;
  TimestampNs last_base_ns_ = 0;
  double last_fore_aft_m_ = 0.0;
  double roll_rad_ = 0.0;
  double pitch_rad_ = 0.0;
  GpsObservation antenna_fix_;  // the last fix, with the mount as the filter took it
  bool have_carrier_phase_fix_ = false;
  TimestampNs last_carrier_phase_fix_ns_ = 0;
  TimestampNs last_code_fix_ns_ = 0;
  bool have_height_ = false;
  double height_m_ = 0.0;
  TimestampNs last_height_ns_ = 0;
  std::uint64_t recorded_steps_ = 0;
  std::span<Attitude> attitudes_;  // a ring, oldest at attitude_first_
  std::size_t attitude_first_ = 0;
  std::size_t attitude_count_ = 0;
  std::span<Pose2> scratch_;  // working space for the planar poses (not state)
  // The map pose: the newest, the correction still to make, the filter's odometry
  // calibration as of the last fix, and a ring of the last map_pose_capacity of them.
  bool map_started_ = false;
  Pose3 map_pose_;
  double pending_x_m_ = 0.0;
  double pending_y_m_ = 0.0;
  double pending_yaw_rad_ = 0.0;
  double distance_scale_ = 1.0;
  double yaw_rate_bias_radps_ = 0.0;
  std::span<Pose3> map_poses_;                // a ring, oldest at map_first_
  Pose2 odometry_pose_;                       // raw dead reckoning, never pulled
  std::span<Pose2> odometry_poses_;           // with each of map_poses_, at the same index
  std::array<TimestampNs, 8> snap_stamps_{};  // the last snaps' stamps (a ring)
  std::size_t snap_next_ = 0;
  std::size_t snap_count_ = 0;
  std::size_t map_first_ = 0;
  std::size_t map_count_ = 0;
  // With a lag: the base samples not yet drawn (a ring, oldest at lagged_first_), and when
  // the lagged map pose was last drawn toward the smoothed path.
  std::span<BaseMotion> lagged_;
  std::size_t lagged_first_ = 0;
  std::size_t lagged_count_ = 0;
  TimestampNs last_pull_ns_ = 0;
};

}  // namespace blockmap::localize
