// The mapper's rigid path: the whole run's path solved again and again from the matched scans
// and every fix (localize::PathSmoother), and where that puts the planes drawn with the poses
// of their time (docs/localize.md, "In the mapper"). As the registry's view (map::PlaneView)
// it moves each plane by the corrections of the keyframes that drew it; between passes it
// ties a wall seen again to its earlier look.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/localize/loop_closer.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "blockmap/map/plane_registry.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::pipeline {

struct RigidPathCounters {
  std::uint64_t fixes_dropped = 0;    // fixes that waited for a matched scan too long
  std::uint64_t ties_other_side = 0;  // a wall paired with one seen from behind
  std::uint64_t planes_moved = 0;     // final planes the end's solve moved
};

class RigidPathSolver final : public map::PlaneView {
 public:
  void init(Arena& arena, const localize::PathSmootherConfig& config,
            const localize::LoopClosureConfig& loops);
  [[nodiscard]] static std::size_t arena_bytes(const localize::PathSmootherConfig& config,
                                               const localize::LoopClosureConfig& loops) noexcept {
    return localize::PathSmoother::arena_bytes(config) + localize::LoopCloser::arena_bytes(loops);
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
  // The end: the whole run's path once more (before the last planes are finalized, so that
  // they are shown where it puts them), then every final plane moved there for good.
  void solve_final() noexcept;
  void move_finals(map::PlaneRegistry& registry) noexcept;

  // Each wall of a detection that continues a final wall of an earlier pass (the same wall
  // drawn with that pass's poses) ties the keyframes that drew the two.
  void tie_walls_to_earlier_passes(std::span<const msg::PlanePatch> detected,
                                   const map::PlaneRegistry& registry,
                                   TimestampNs stamp_ns) noexcept;
  // The final wall that `wall` is an earlier pass's drawing of, or final_planes().size().
  [[nodiscard]] static std::size_t earlier_drawing_of(const msg::PlanePatch& wall,
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
  [[nodiscard]] RigidPathCounters counters() const noexcept {
    return {fixes_.dropped_oldest().value(), ties_other_side_, planes_moved_};
  }

 private:
  // Whether anything but the odometry says where the path lies: fixes or loop closures.
  [[nodiscard]] bool placed() const noexcept {
    return path_.counters().fixes > 0 || path_.closure_count() > 0;
  }
  // The first keyframe stamped at or after `stamp_ns` (keyframe_count() when none is).
  [[nodiscard]] std::size_t first_keyframe_from(TimestampNs stamp_ns) const noexcept;
  // The keyframe nearest `point_m` (x, y) among those from `from_ns` to `to_ns` that `seen`
  // covers (every one when null): its stamp and drawn position; false when none is in reach.
  bool keyframe_that_drew(const Eigen::Vector2d& point_m, TimestampNs from_ns, TimestampNs to_ns,
                          const map::SeenSpans* seen, TimestampNs& stamp_ns,
                          Eigen::Vector2d& from_m) const noexcept;

  localize::PathSmoother path_;
  // Revisits found by matching submaps, as constraints on path_.
  localize::LoopCloser closer_;
  std::array<localize::LoopClosure, localize::kMaxClosureCandidates> found_{};
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
