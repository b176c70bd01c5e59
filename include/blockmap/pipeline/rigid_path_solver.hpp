// The mapper's rigid path: the whole run's path solved again and again from the matched scans
// and every fix (localize::PathSmoother), and where that puts the planes drawn with the poses
// of their time (docs/localize.md, "In the mapper"). As the registry's view (map::PlaneView)
// it moves each plane by the corrections of the keyframes that drew it; between passes it
// ties a wall seen again to its earlier look.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/localize/loop_closer.hpp"
#include "blockmap/localize/map_localizer.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "blockmap/map/plane_registry.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::pipeline {

struct RigidPathCounters {
  std::uint64_t fixes_dropped = 0;     // fixes that waited for a matched scan too long
  std::uint64_t ties_other_side = 0;   // a wall paired with one seen from behind
  std::uint64_t planes_moved = 0;      // final planes the end's solve moved
  std::uint64_t placings_refused = 0;  // a prior map's placings far from the path
  std::uint64_t map_restarts = 0;      // ... so many in a row that its particles started again
};

class RigidPathSolver final : public map::PlaneView {
 public:
  void init(Arena& arena, const localize::PathSmootherConfig& config,
            const localize::LoopClosureConfig& loops, const localize::PriorMapConfig& prior_map);
  [[nodiscard]] static std::size_t arena_bytes(const localize::PathSmootherConfig& config,
                                               const localize::LoopClosureConfig& loops,
                                               const localize::PriorMapConfig& prior_map) noexcept {
    return localize::PathSmoother::arena_bytes(config) + localize::LoopCloser::arena_bytes(loops) +
           localize::MapLocalizer::arena_bytes(prior_map);
  }
  // The robot started at a known pose, within these sigmas: the path's start is held there
  // (no fix needed to place it). After init.
  void start_placed(double sigma_m, double yaw_sigma_rad) noexcept;
  // The prior map's walls, at start-up (prior_map enabled): empty when it worked, else why not.
  [[nodiscard]] std::string set_prior_map(std::span<const localize::MapWall> walls) {
    return on_map_.set_map(walls);
  }

  // A fix the localizer took, as the robot frame's position: it waits for the first matched
  // scan at or after it (the scans are drawn later than the fixes are released).
  void add_fix(const localize::GpsObservation& robot_fix) noexcept;
  // The scan matcher's frame starts over (its grid was reset): the next matched pose is laid
  // where the dead reckoning carries the last one.
  void rebase() noexcept { rebase_due_ = true; }
  // A level scan: `matched` in the matcher's frame, `drawn` where it was drawn, `odometry`
  // the dead-reckoned pose at its time; `scan_matched` false when the prediction stood (the
  // motion to it is the odometry's alone), `match_points_m` the points its match used in
  // the robot frame (the loop closer's submaps). Solves again every 10 s of scan time.
  void add_matched_scan(TimestampNs stamp_ns, const localize::Pose2& matched,
                        const localize::Pose2& drawn, const localize::Pose2& odometry,
                        bool scan_matched,
                        std::span<const Eigen::Vector2d> match_points_m) noexcept;
  // Whether a solve came since the last call (the view is due for a refresh).
  [[nodiscard]] bool take_solved() noexcept;
  // The end: the last submap's revisits, and the whole run's path once more (before the last
  // planes are finalized, so that they are shown where it puts them), then every final plane
  // moved there for good.
  void solve_final() noexcept;
  void move_finals(map::PlaneRegistry& registry) noexcept;

  // Each wall of a detection that continues a final wall of an earlier pass (the same wall
  // drawn with that pass's poses) ties the keyframes that drew the two.
  void tie_walls_to_earlier_passes(std::span<const msg::PlanePatch> detected,
                                   const map::PlaneRegistry& registry,
                                   TimestampNs stamp_ns) noexcept;
  // The final wall that `drawn_wall` (which the path moves by `wall_move`) is an earlier
  // pass's drawing of, or final_planes().size().
  [[nodiscard]] static std::size_t earlier_drawing_of(const msg::PlanePatch& drawn_wall,
                                                      const map::PlaneMove& wall_move,
                                                      const map::PlaneRegistry& registry,
                                                      TimestampNs stamp_ns) noexcept;
  // The later look's keyframe: one of this pass, the last half minute.
  static constexpr TimestampNs kThisPassNs = 30 * kNanosecondsPerSecond;

  // Where the solved path puts a plane drawn with the poses of its time, seen at the times
  // `seen` holds (the identity before the path has fixes and a solve, with no keyframe near,
  // or for a plane from a snapshot, which has no spans).
  [[nodiscard]] map::PlaneMove move_of(const msg::PlanePatch& plane,
                                       const map::SeenSpans& seen) const noexcept override;

  [[nodiscard]] const localize::PathSmoother& path() const noexcept { return path_; }
  [[nodiscard]] const localize::LoopCloser& loop_closer() const noexcept { return closer_; }
  [[nodiscard]] const localize::MapLocalizer& map_localizer() const noexcept { return on_map_; }
  [[nodiscard]] RigidPathCounters counters() const noexcept {
    return {fixes_.dropped_oldest().value(), ties_other_side_, planes_moved_, placings_refused_,
            map_restarts_};
  }

 private:
  // Whether anything but the odometry says where the path lies: fixes, a prior map's
  // placings or loop closures.
  [[nodiscard]] bool placed() const noexcept {
    return path_.holds_first() || path_.counters().fixes > 0 || path_.counters().placings > 0 ||
           path_.closure_count() > 0;
  }
  // The submap just finished matched against the earlier ones: its verified revisits into
  // the path.
  void close_loops() noexcept;
  // The first keyframe stamped at or after `stamp_ns` (keyframe_count() when none is).
  [[nodiscard]] std::size_t first_keyframe_from(TimestampNs stamp_ns) const noexcept;
  // The keyframe nearest `point_m` (x, y) among those from `from_ns` to `to_ns` that `seen`
  // covers (every one when null): its stamp and drawn position; false when none is in reach.
  bool keyframe_that_drew(const Eigen::Vector2d& point_m, TimestampNs from_ns, TimestampNs to_ns,
                          const map::SeenSpans* seen, TimestampNs& stamp_ns,
                          Eigen::Vector2d& from_m) const noexcept;
  // The map localizer at a matched scan: started once the path is placed, then its placings.
  void localize_on_map(const localize::Pose2& in_path, const localize::Pose2& drawn_at,
                       std::span<const Eigen::Vector2d> match_points_m) noexcept;
  // The solved path's pose at `in_path` in the prior map's frame (its offset added when the
  // path carries it).
  [[nodiscard]] localize::Pose2 on_map(const localize::Pose2& in_path) const noexcept;
  // Its particles again around the solved path's pose at `in_path`.
  void restart_map_localizer(const localize::Pose2& in_path) noexcept;

  localize::PathSmoother path_;
  // Revisits found by matching submaps, as constraints on path_.
  localize::LoopCloser closer_;
  std::array<localize::LoopClosure, localize::kMaxClosureCandidates> found_{};
  // Where a prior map puts the robot (Monte Carlo localization), as placings on path_.
  localize::MapLocalizer on_map_;
  std::uint32_t refused_in_a_row_ = 0;
  std::uint64_t placings_refused_ = 0;
  std::uint64_t map_restarts_ = 0;
  double start_sigma_m_ = 0.0;  // where the map localizer's particles start
  double start_yaw_sigma_rad_ = 0.0;
  double travelled_m_ = 0.0;         // the path's length so far
  double solved_travelled_m_ = 0.0;  // ... at the last solve
  bool starts_placed_ = false;
  RingBuffer<localize::GpsObservation, 64> fixes_;  // waiting for a matched scan
  TimestampNs next_solve_ns_ = 0;
  bool solved_ = false;
  // The matcher's frame starts over when the filter's poses snap; the path's odometry goes on
  // across: rebase_ takes matched poses into the path's one frame.
  localize::PlanarCorrection rebase_;
  bool rebase_due_ = false;
  bool have_last_ = false;
  localize::Pose2 last_pose_;
  localize::Pose2 last_odometry_;
  std::uint64_t ties_other_side_ = 0;
  std::uint64_t planes_moved_ = 0;
};

}  // namespace blockmap::pipeline
