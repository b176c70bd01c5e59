#include "blockmap/pipeline/rigid_path_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"

namespace blockmap::pipeline {
namespace {

// Every 10 s of scan time the path is solved again, so that each solve starts near its answer
// (a sweep is O(keyframes)).
constexpr TimestampNs kSolveEveryNs = 10'000'000'000;
// A plane is drawn by the keyframes within the lasers' reach of it, and a detection holds
// points drawn up to kLeadNs before the plane was first matched (it takes points before it is
// found).
constexpr double kReachM = 30.0;
constexpr TimestampNs kLeadNs = 10 * kNanosecondsPerSecond;

// A wall's extent along its own direction (`along`, horizontal) and in height.
struct WallExtent {
  double from_m = std::numeric_limits<double>::infinity();
  double to_m = -std::numeric_limits<double>::infinity();
  double low_m = std::numeric_limits<double>::infinity();
  double high_m = -std::numeric_limits<double>::infinity();
};

WallExtent wall_extent(const msg::PlanePatch& wall, const Eigen::Vector2d& along) noexcept {
  WallExtent extent;
  for (std::size_t v = 0; v < wall.polygon_size; ++v) {
    const Eigen::Vector3d& vertex = wall.polygon_m[v];
    const double at_m = along.dot(vertex.head<2>());
    extent.from_m = std::min(extent.from_m, at_m);
    extent.to_m = std::max(extent.to_m, at_m);
    extent.low_m = std::min(extent.low_m, vertex.z());
    extent.high_m = std::max(extent.high_m, vertex.z());
  }
  return extent;
}

double overlap_m(double a_from, double a_to, double b_from, double b_to) noexcept {
  return std::min(a_to, b_to) - std::max(a_from, b_from);
}

}  // namespace

void RigidPathSolver::init(Arena& arena, const localize::PathSmootherConfig& config,
                           const localize::LoopClosureConfig& loops,
                           const localize::PriorMapConfig& prior_map) {
  path_.init(arena, config);
  closer_.init(arena, loops);
  on_map_.init(arena, prior_map);
  start_sigma_m_ = prior_map.start_sigma_m;
  start_yaw_sigma_rad_ = prior_map.start_yaw_sigma_deg * kRadiansPerDegree;
}

void RigidPathSolver::start_placed(double sigma_m, double yaw_sigma_rad) noexcept {
  starts_placed_ = true;
  path_.hold_first(sigma_m, yaw_sigma_rad);
  start_sigma_m_ = sigma_m;
  start_yaw_sigma_rad_ = yaw_sigma_rad;
  const localize::PriorMapConfig& map = on_map_.config();
  if (map.enabled && map.frame_sigma_m > 0.0) {
    path_.carry_map_offset(map.frame_sigma_m, map.frame_time_s);
    start_sigma_m_ = std::hypot(sigma_m, map.frame_sigma_m);
  }
}

localize::Pose2 RigidPathSolver::on_map(const localize::Pose2& in_path) const noexcept {
  localize::Pose2 pose = path_.solved_pose(in_path);
  if (path_.carries_map_offset()) {
    const Eigen::Vector2d offset_m = path_.slow_error(in_path);
    pose.x_m += offset_m.x();
    pose.y_m += offset_m.y();
  }
  return pose;
}

void RigidPathSolver::localize_on_map(const localize::Pose2& in_path,
                                      const localize::Pose2& drawn_at,
                                      std::span<const Eigen::Vector2d> match_points_m) noexcept {
  if (!on_map_.ready()) {
    return;
  }
  const localize::PriorMapConfig& config = on_map_.config();
  if (!on_map_.started()) {
    // The path's own frame is the matcher's, turned anyhow: the particles start in the local
    // frame, where the solved path puts the robot once it is placed.
    if (starts_placed_ ||
        (path_.counters().fixes > 0 && solved_travelled_m_ >= config.start_after_m)) {
      on_map_.start(on_map(in_path), in_path, start_sigma_m_, start_yaw_sigma_rad_);
    }
    return;
  }
  localize::MapPlacing placing;
  const bool placed_here = on_map_.add_scan(in_path, match_points_m, placing);
  if (on_map_.lost()) {
    restart_map_localizer(in_path);
    return;
  }
  if (!placed_here) {
    return;
  }
  const localize::Pose2 solved = on_map(in_path);
  const double gate_m = path_.counters().placings > 0
                            ? config.placing_gate_m
                            : std::max(config.placing_gate_m, 3.0 * start_sigma_m_);
  if (std::hypot(placing.pose.x_m - solved.x_m, placing.pose.y_m - solved.y_m) > gate_m) {
    ++placings_refused_;
    if (++refused_in_a_row_ >= config.restart_after) {
      restart_map_localizer(in_path);
    }
    return;
  }
  refused_in_a_row_ = 0;
  path_.place(in_path, drawn_at, Eigen::Vector2d(placing.pose.x_m, placing.pose.y_m),
              placing.information);
}

void RigidPathSolver::restart_map_localizer(const localize::Pose2& in_path) noexcept {
  on_map_.start(on_map(in_path), in_path,
                std::max(start_sigma_m_, on_map_.config().placing_gate_m / 3.0),
                start_yaw_sigma_rad_);
  refused_in_a_row_ = 0;
  ++map_restarts_;
}

void RigidPathSolver::add_fix(const localize::GpsObservation& robot_fix) noexcept {
  fixes_.push_overwrite(robot_fix);
}

void RigidPathSolver::add_matched_scan(TimestampNs stamp_ns, const localize::Pose2& matched,
                                       const localize::Pose2& drawn,
                                       const localize::Pose2& odometry, bool scan_matched,
                                       std::span<const Eigen::Vector2d> match_points_m) noexcept {
  if (rebase_due_ && have_last_) {
    // Where the dead reckoning carries the last pose (the rigid motion that lays the last
    // odometry pose on the last path pose, applied to this one): the new frame's first pose
    // goes there.
    const localize::Pose2 carried =
        localize::motion_between(last_odometry_, last_pose_).apply(odometry);
    rebase_ = localize::motion_between(matched, carried);
  }
  rebase_due_ = false;
  localize::Pose2 in_path = rebase_.apply(matched);
  in_path.stamp_ns = stamp_ns;
  if (have_last_) {
    // Noted for every scan, so that the path knows its odometry is matched scans.
    const bool alone = !scan_matched;
    const double since_last_s = seconds_from_ns(stamp_ns - last_pose_.stamp_ns);
    path_.note_dead_reckoning(
        alone ? std::hypot(in_path.x_m - last_pose_.x_m, in_path.y_m - last_pose_.y_m) : 0.0,
        alone ? since_last_s : 0.0, alone ? 0.0 : since_last_s);
  }
  if (have_last_) {
    travelled_m_ += std::hypot(in_path.x_m - last_pose_.x_m, in_path.y_m - last_pose_.y_m);
  }
  have_last_ = true;
  last_pose_ = in_path;
  last_odometry_ = odometry;
  localize::Pose2 drawn_at = drawn;
  drawn_at.stamp_ns = stamp_ns;
  bool added = false;
  while (!fixes_.empty() && fixes_[0].stamp_ns <= stamp_ns) {
    const localize::GpsObservation& fix = fixes_[0];
    path_.add(in_path, drawn_at, Eigen::Vector2d(fix.east_m, fix.north_m), std::max(fix.hdop, 0.5),
              fix.correction);
    fixes_.pop_front();
    added = true;
  }
  if (!added) {
    path_.add(in_path, drawn_at, std::nullopt);
  }
  if (scan_matched) {
    localize_on_map(in_path, drawn_at, match_points_m);
  }
  // A finished submap is matched against the earlier ones near it: the verified revisits
  // hold the passes to each other.
  if (scan_matched && closer_.add_scan(in_path, match_points_m)) {
    close_loops();
  }
  if (stamp_ns >= next_solve_ns_) {
    path_.solve();
    solved_ = true;
    solved_travelled_m_ = travelled_m_;
    next_solve_ns_ = stamp_ns + kSolveEveryNs;
  }
}

bool RigidPathSolver::take_solved() noexcept {
  const bool solved = solved_;
  solved_ = false;
  return solved;
}

void RigidPathSolver::close_loops() noexcept {
  const std::size_t closures = closer_.find_closures(path_, found_);
  for (std::size_t k = 0; k < closures; ++k) {
    path_.close_loop(found_[k]);
  }
}

void RigidPathSolver::solve_final() noexcept {
  if (closer_.finish_last_submap()) {
    close_loops();
  }
  if (placed()) {
    path_.solve();
  }
}

void RigidPathSolver::move_finals(map::PlaneRegistry& registry) noexcept {
  planes_moved_ += registry.move_finals_by(*this);
}

std::size_t RigidPathSolver::first_keyframe_from(TimestampNs stamp_ns) const noexcept {
  std::size_t low = 0;
  std::size_t high = path_.keyframe_count();
  while (low < high) {
    const std::size_t middle = low + (high - low) / 2;
    if (path_.drawn(middle).stamp_ns < stamp_ns) {
      low = middle + 1;
    } else {
      high = middle;
    }
  }
  return low;
}

map::PlaneMove RigidPathSolver::move_of(const msg::PlanePatch& plane,
                                        const map::SeenSpans& seen) const noexcept {
  // A plane moves by the corrections of the keyframes that drew it: near it (nearer ones
  // more: they put more points on it) while it was being seen (a pass behind the building, as
  // near, did not draw it), averaged: a turn about the vertical and where its centroid goes.
  constexpr double kNearM = 2.0;
  // Without fixes or loop closures nothing says where the path lies but its own odometry,
  // which the scans were drawn with already (a log with no GPS and no revisit): the planes
  // stay.
  // A plane without seen spans comes from a snapshot: the run that saved it placed it.
  const std::size_t keyframes = path_.keyframe_count();
  if (!placed() || path_.counters().solves == 0 || keyframes < 2 || seen.count == 0) {
    return {};
  }
  Eigen::AlignedBox2d extent;
  for (std::size_t v = 0; v < plane.polygon_size; ++v) {
    extent.extend(plane.polygon_m[v].head<2>());
  }
  if (extent.isEmpty()) {
    extent.extend(plane.centroid_m.head<2>());
  }
  // The keyframes of its spans (they are in time order).
  const std::size_t first = first_keyframe_from(seen.first_ns() - kLeadNs);
  const std::size_t end = first_keyframe_from(seen.last_ns() + 1);
  const Eigen::Vector2d centroid_m = plane.centroid_m.head<2>();
  double weight_sum = 0.0;
  double yaw_sum_rad = 0.0;
  Eigen::Vector2d moved_sum_m = Eigen::Vector2d::Zero();
  for (std::size_t k = first; k < end; ++k) {
    const localize::Pose2& drawn = path_.drawn(k);
    if (!seen.covers(drawn.stamp_ns, kLeadNs)) {
      continue;
    }
    const double distance_m =
        std::sqrt(extent.squaredExteriorDistance(Eigen::Vector2d(drawn.x_m, drawn.y_m)));
    if (distance_m > kReachM) {
      continue;
    }
    const double weight = 1.0 / std::max(distance_m * distance_m, kNearM * kNearM);
    const localize::PlanarCorrection correction = path_.correction(k);
    weight_sum += weight;
    yaw_sum_rad += weight * correction.yaw_rad;
    moved_sum_m += weight * correction.apply(centroid_m);
  }
  if (weight_sum <= 0.0) {
    return {};
  }
  map::PlaneMove move;
  move.yaw_rad = yaw_sum_rad / weight_sum;
  const Eigen::Vector2d to_m = moved_sum_m / weight_sum;
  move.shift_m = Eigen::Vector3d(to_m.x(), to_m.y(), plane.centroid_m.z()) -
                 move.rotation() * plane.centroid_m;
  return move;
}

void RigidPathSolver::tie_walls_to_earlier_passes(std::span<const msg::PlanePatch> detected,
                                                  const map::PlaneRegistry& registry,
                                                  TimestampNs stamp_ns) noexcept {
  const std::span<const msg::PlanePatch> finals = registry.final_planes();
  // Where the path now puts what this pass draws, as the stream shows the final planes: by
  // its latest keyframe's correction (as drawn without a view).
  map::PlaneMove move_now;
  if (registry.has_view() && path_.keyframe_count() > 0) {
    const localize::PlanarCorrection latest = path_.correction(path_.keyframe_count() - 1);
    move_now = {latest.yaw_rad, Eigen::Vector3d(latest.x_m, latest.y_m, 0.0)};
  }
  for (const msg::PlanePatch& wall : detected) {
    if (wall.kind != msg::PlaneKind::kWall || wall.normal.head<2>().norm() < 0.5) {
      continue;
    }
    const std::size_t best = earlier_drawing_of(wall, move_now, registry, stamp_ns);
    if (best == finals.size()) {
      continue;
    }
    const msg::PlanePatch& earlier = finals[best];
    const map::SeenSpans& seen = registry.seen_spans(best);
    localize::WallLook before{0, earlier.normal.head<2>().normalized(),
                              earlier.centroid_m.head<2>()};
    localize::WallLook now{0, wall.normal.head<2>().normalized(), wall.centroid_m.head<2>()};
    Eigen::Vector2d before_from_m;
    Eigen::Vector2d now_from_m;
    if (!keyframe_that_drew(before.point_m, seen.first_ns(), seen.last_ns(), &seen, before.stamp_ns,
                            before_from_m) ||
        !keyframe_that_drew(now.point_m, stamp_ns - kThisPassNs, stamp_ns, nullptr, now.stamp_ns,
                            now_from_m)) {
      continue;
    }
    // Both looks from the same side: a wall's two faces (or two walls back to back) are not
    // one surface.
    if (before.normal.dot(before_from_m - before.point_m) *
            before.normal.dot(now_from_m - now.point_m) <=
        0.0) {
      ++ties_other_side_;
      continue;
    }
    path_.tie(earlier.id, before, now);
  }
}

std::size_t RigidPathSolver::earlier_drawing_of(const msg::PlanePatch& drawn_wall,
                                                const map::PlaneMove& wall_move,
                                                const map::PlaneRegistry& registry,
                                                TimestampNs stamp_ns) noexcept {
  // Compared where the path puts them: each pass's drawing, moved as the stream shows it. As
  // drawn, a loop's end lies as far off its start as the lasers drifted round it.
  // A pass's poses put its walls off by the receiver's slow error of that time, up to a
  // couple of metres, and another pass's by another: the same wall drawn twice lies up to
  // kGateM apart, parallel to within kGateAngleDeg. It must overlap the earlier drawing by
  // kMinOverlapM along the wall and in height (the walls of a street's next building are in
  // line with it, but further on), and the earlier pass must have ended kOtherPassNs before
  // (a wall left behind by this pass is no earlier pass). Of several, the nearest.
  constexpr double kGateM = 2.0;
  constexpr double kGateAngleDeg = 5.0;
  constexpr double kMinOverlapM = 2.0;
  constexpr double kMinHeightOverlapM = 0.5;
  constexpr TimestampNs kOtherPassNs = 2 * map::SeenSpans::kJoinGapNs;
  const double cos_gate_angle = std::cos(radians_from_degrees(kGateAngleDeg));
  const std::span<const msg::PlanePatch> finals = registry.final_planes();
  msg::PlanePatch wall = drawn_wall;
  map::move_plane(wall, wall_move);
  const Eigen::Vector2d normal = wall.normal.head<2>().normalized();
  const Eigen::Vector2d along(-normal.y(), normal.x());
  const WallExtent extent = wall_extent(wall, along);
  std::size_t best = finals.size();
  double best_offset_m = kGateM;
  for (std::size_t j = 0; j < finals.size(); ++j) {
    const map::SeenSpans& seen = registry.seen_spans(j);
    if (finals[j].kind != msg::PlaneKind::kWall || seen.count == 0 ||
        stamp_ns - seen.last_ns() < kOtherPassNs) {
      continue;
    }
    const map::PlaneMove& shown = registry.final_shown(j);
    const Eigen::Vector2d earlier_normal =
        Eigen::Rotation2Dd(shown.yaw_rad) * finals[j].normal.head<2>().normalized();
    if (std::abs(earlier_normal.dot(normal)) < cos_gate_angle) {
      continue;
    }
    msg::PlanePatch earlier = finals[j];
    map::move_plane(earlier, shown);
    const double offset_m = std::abs(earlier.normal.dot(wall.centroid_m) - earlier.d_m);
    if (offset_m >= best_offset_m) {
      continue;
    }
    const WallExtent before = wall_extent(earlier, along);
    // A level laser alone draws its walls a hand high: half of the lower drawing will do.
    const double min_height_overlap_m =
        std::min(kMinHeightOverlapM,
                 0.5 * std::min(extent.high_m - extent.low_m, before.high_m - before.low_m));
    if (overlap_m(extent.from_m, extent.to_m, before.from_m, before.to_m) < kMinOverlapM ||
        overlap_m(extent.low_m, extent.high_m, before.low_m, before.high_m) <
            min_height_overlap_m) {
      continue;
    }
    best = j;
    best_offset_m = offset_m;
  }
  return best;
}

bool RigidPathSolver::keyframe_that_drew(const Eigen::Vector2d& point_m, TimestampNs from_ns,
                                         TimestampNs to_ns, const map::SeenSpans* seen,
                                         TimestampNs& stamp_ns,
                                         Eigen::Vector2d& from_m) const noexcept {
  // Within the lasers' reach of the wall's middle, the nearest (it put the most points there).
  double best_m2 = kReachM * kReachM;
  bool found = false;
  // Back from the last keyframe of the time (the keyframes are in time order).
  for (std::size_t k = first_keyframe_from(to_ns + 1); k-- > 0;) {
    const localize::Pose2& drawn = path_.drawn(k);
    if (drawn.stamp_ns < from_ns - kLeadNs) {
      break;
    }
    if (seen != nullptr && !seen->covers(drawn.stamp_ns, kLeadNs)) {
      continue;
    }
    const double distance_m2 = (Eigen::Vector2d(drawn.x_m, drawn.y_m) - point_m).squaredNorm();
    if (distance_m2 < best_m2) {
      best_m2 = distance_m2;
      stamp_ns = drawn.stamp_ns;
      from_m = Eigen::Vector2d(drawn.x_m, drawn.y_m);
      found = true;
    }
  }
  return found;
}

}  // namespace blockmap::pipeline
