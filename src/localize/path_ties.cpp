// PathSmoother's ties between passes: a wall seen on two passes of the robot, whose looks
// must agree; kept while there is room (the most alike give way when full), linearized about
// the path at each solve, and their pull on the gradient.
#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "path_state.hpp"

namespace blockmap::localize {

using path_state::kX;
using path_state::kY;
using path_state::kYaw;

bool PathSmoother::tie(std::uint32_t key, const WallLook& earlier, const WallLook& later) noexcept {
  if (count_ == 0) {
    return false;
  }
  Tie candidate;
  candidate.key = key;
  candidate.earlier = earlier;
  candidate.later = later;
  // One side: the residual's turn compares the normals' directions.
  if (earlier.normal.dot(later.normal) < 0.0) {
    candidate.later.normal = -later.normal;
  }
  for (std::size_t i = tie_count_; i-- > 0;) {
    Tie& kept = ties_[i];
    if (kept.key == key && later.stamp_ns >= kept.later.stamp_ns &&
        later.stamp_ns - kept.later.stamp_ns < kSamePassNs) {
      kept = candidate;
      ++counters_.ties_refreshed;
      return true;
    }
  }
  if (tie_count_ < ties_.size()) {
    ties_[tie_count_++] = candidate;
    ++counters_.ties;
    return true;
  }
  const std::size_t slot = spare_tie_slot(candidate);
  if (slot == ties_.size()) {
    ++counters_.ties_dropped;
    return false;
  }
  ties_[slot] = candidate;
  ++counters_.ties;
  ++counters_.ties_replaced;
  return true;
}

TimestampNs PathSmoother::tie_likeness_ns(const Tie& p, const Tie& q) noexcept {
  // Walls within 45 degrees of each other count as parallel: a city block's are square.
  constexpr double kParallelCos = 0.7071;
  if (std::abs(p.earlier.normal.dot(q.earlier.normal)) < kParallelCos) {
    return std::numeric_limits<TimestampNs>::max();
  }
  const auto apart = [](TimestampNs a, TimestampNs b) { return a > b ? a - b : b - a; };
  return std::max(apart(p.earlier.stamp_ns, q.earlier.stamp_ns),
                  apart(p.later.stamp_ns, q.later.stamp_ns));
}

std::size_t PathSmoother::spare_tie_slot(const Tie& candidate) const noexcept {
  std::size_t slot = ties_.size();  // the new one, unless two kept ones are more alike
  TimestampNs closest_ns = std::numeric_limits<TimestampNs>::max();
  for (std::size_t i = 0; i < tie_count_; ++i) {
    const TimestampNs likeness_ns = tie_likeness_ns(ties_[i], candidate);
    closest_ns = std::min(closest_ns, likeness_ns);
  }
  for (std::size_t i = 0; i < tie_count_; ++i) {
    for (std::size_t j = i + 1; j < tie_count_; ++j) {
      const TimestampNs likeness_ns = tie_likeness_ns(ties_[i], ties_[j]);
      if (likeness_ns < closest_ns) {
        closest_ns = likeness_ns;
        slot = ties_[i].later.stamp_ns <= ties_[j].later.stamp_ns ? i : j;
      }
    }
  }
  return slot;
}

std::size_t PathSmoother::keyframe_nearest(TimestampNs stamp_ns) const noexcept {
  const auto first = keyframes_.begin();
  const auto last = first + static_cast<std::ptrdiff_t>(count_);
  const auto after = std::lower_bound(first, last, stamp_ns, [](const Keyframe& k, TimestampNs t) {
    return k.odometry.stamp_ns < t;
  });
  if (after == first) {
    return 0;
  }
  if (after == last) {
    return count_ - 1;
  }
  const auto index = static_cast<std::size_t>(after - first);
  const TimestampNs to_after = after->odometry.stamp_ns - stamp_ns;
  const TimestampNs to_before = stamp_ns - keyframes_[index - 1].odometry.stamp_ns;
  return to_before <= to_after ? index - 1 : index;
}

void PathSmoother::linearize_tie(Tie& tie) const noexcept {
  // Each look moved by its keyframe's correction, drawn -> solved: a turn by
  // yaw - drawn yaw about the drawn position, then to the solved position.
  struct Moved {
    Eigen::Vector2d normal;
    Eigen::Vector2d point_m;
    Eigen::Vector2d lever_m;  // from the solved position to the point
  };
  const auto move = [this](std::size_t k, const WallLook& look) {
    const Keyframe& keyframe = keyframes_[k];
    const double turn_rad = keyframe.state[kYaw] - keyframe.drawn.yaw_rad;
    const Eigen::Rotation2Dd rotation(turn_rad);
    const Eigen::Vector2d from_m(keyframe.drawn.x_m, keyframe.drawn.y_m);
    const Eigen::Vector2d to_m(keyframe.state[kX], keyframe.state[kY]);
    Moved moved;
    moved.normal = rotation * look.normal;
    moved.lever_m = rotation * (look.point_m - from_m);
    moved.point_m = to_m + moved.lever_m;
    return moved;
  };
  const auto perpendicular = [](const Eigen::Vector2d& v) {
    return Eigen::Vector2d(-v.y(), v.x());
  };
  tie.a = keyframe_nearest(tie.earlier.stamp_ns);
  tie.b = keyframe_nearest(tie.later.stamp_ns);
  const Moved a = move(tie.a, tie.earlier);
  const Moved b = move(tie.b, tie.later);
  const Eigen::Vector2d apart_m = b.point_m - a.point_m;
  // Offset: the later look's point from the earlier look's plane; turn: between the normals.
  tie.residual[0] = a.normal.dot(apart_m);
  tie.residual[1] =
      wrap_angle(std::atan2(b.normal.y(), b.normal.x()) - std::atan2(a.normal.y(), a.normal.x()));
  tie.jacobian_a[0] = -a.normal.x();
  tie.jacobian_a[1] = -a.normal.y();
  tie.jacobian_a[2] = perpendicular(a.normal).dot(apart_m) - a.normal.dot(perpendicular(a.lever_m));
  tie.jacobian_a[3] = 0.0;
  tie.jacobian_a[4] = 0.0;
  tie.jacobian_a[5] = -1.0;
  tie.jacobian_b[0] = a.normal.x();
  tie.jacobian_b[1] = a.normal.y();
  tie.jacobian_b[2] = a.normal.dot(perpendicular(b.lever_m));
  tie.jacobian_b[3] = 0.0;
  tie.jacobian_b[4] = 0.0;
  tie.jacobian_b[5] = 1.0;
  const double sigmas[2] = {config_.tie_offset_sigma_m,
                            radians_from_degrees(config_.tie_angle_sigma_deg)};
  // Looks whose walls turn apart by more than the gate once moved were not drawn with
  // these keyframes' poses (a filter still settling drew one): the tie is left out.
  const bool gated = std::abs(tie.residual[1]) > radians_from_degrees(config_.tie_gate_deg);
  for (int r = 0; r < 2; ++r) {
    if (gated) {
      tie.weight[r] = 0.0;
      continue;
    }
    // Huber: beyond tie_huber_sigmas the weight falls as 1/|residual|, a constant pull.
    const double normalized = std::abs(tie.residual[r]) / sigmas[r];
    const double huber =
        normalized <= config_.tie_huber_sigmas ? 1.0 : config_.tie_huber_sigmas / normalized;
    tie.weight[r] = huber / (sigmas[r] * sigmas[r]);
  }
}

void PathSmoother::accumulate_tie_gradient(const Tie& tie) noexcept {
  for (int r = 0; r < 2; ++r) {
    const double weighted = tie.weight[r] * tie.residual[r];
    for (int c = 0; c < 3; ++c) {
      blocks_[tie.a].gradient[c] += tie.jacobian_a[3 * r + c] * weighted;
      blocks_[tie.b].gradient[c] += tie.jacobian_b[3 * r + c] * weighted;
    }
  }
}

}  // namespace blockmap::localize
