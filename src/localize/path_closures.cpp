// PathSmoother's loop closures: two times of the path whose poses the lasers matched to each
// other; kept while there is room, linearized about the path at each solve, and their pull on
// the gradient and in conjugate gradients' products.
#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "path_state.hpp"

namespace blockmap::localize {

using path_state::kX;
using path_state::kY;
using path_state::kYaw;

namespace {

using RowMatrix3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

Eigen::Vector2d perpendicular(const Eigen::Vector2d& v) noexcept {
  return {-v.y(), v.x()};
}

}  // namespace

void PathSmoother::close_loop(const LoopClosure& closure) noexcept {
  if (closures_.empty()) {
    return;
  }
  if (closure_count_ == closures_.size()) {
    // Every other one of the older half goes: the newest keep their detail, the older the
    // run's shape.
    const std::size_t half = closure_count_ / 2;
    std::size_t kept = 0;
    for (std::size_t i = 0; i < closure_count_; ++i) {
      if (i < half && i % 2 == 1) {
        ++counters_.closures_dropped;
        continue;
      }
      closures_[kept++] = closures_[i];
    }
    closure_count_ = kept;
  }
  closures_[closure_count_++] = Closure{closure};
  ++counters_.closures;
}

Pose2 PathSmoother::solved_pose(const Pose2& odometry) const noexcept {
  BLOCKMAP_CHECK_MSG(count_ > 0, "solved_pose() before the first keyframe");
  const std::size_t k = keyframe_nearest(odometry.stamp_ns);
  const Eigen::Vector3d offset = pose_in_frame_of(keyframes_[k].odometry, odometry);
  const Keyframe& keyframe = keyframes_[k];
  const Eigen::Vector2d at_m = Eigen::Vector2d(keyframe.state[kX], keyframe.state[kY]) +
                               Eigen::Rotation2Dd(keyframe.state[kYaw]) * offset.head<2>();
  return {odometry.stamp_ns, at_m.x(), at_m.y(), wrap_angle(keyframe.state[kYaw] + offset.z())};
}

void PathSmoother::linearize_closure(Closure& c) const noexcept {
  // Each end is its nearest keyframe's solved pose carried by the odometry's offset from it:
  // p = p_k + R(yaw_k) d, yaw = yaw_k + phi. The residual is the later end in the earlier
  // one's frame less what the lasers measured.
  c.a = keyframe_nearest(c.closure.earlier.stamp_ns);
  c.b = keyframe_nearest(c.closure.later.stamp_ns);
  const Keyframe& ka = keyframes_[c.a];
  const Keyframe& kb = keyframes_[c.b];
  const Eigen::Vector3d da = pose_in_frame_of(ka.odometry, c.closure.earlier);
  const Eigen::Vector3d db = pose_in_frame_of(kb.odometry, c.closure.later);
  const Eigen::Vector2d pa(ka.state[kX], ka.state[kY]);
  const Eigen::Vector2d pb(kb.state[kX], kb.state[kY]);
  const Eigen::Vector2d b_lever_m = Eigen::Rotation2Dd(kb.state[kYaw]) * db.head<2>();
  const Eigen::Vector2d end_a = pa + Eigen::Rotation2Dd(ka.state[kYaw]) * da.head<2>();
  const Eigen::Vector2d end_b = pb + b_lever_m;
  const double yaw_a = ka.state[kYaw] + da.z();
  const Eigen::Matrix2d to_a = Eigen::Rotation2Dd(-yaw_a).toRotationMatrix();
  const Eigen::Vector2d apart_m = to_a * (end_b - end_a);
  const Eigen::Vector3d residual(
      apart_m.x() - c.closure.measured.x(), apart_m.y() - c.closure.measured.y(),
      wrap_angle(kb.state[kYaw] + db.z() - yaw_a - c.closure.measured.z()));
  Eigen::Map<RowMatrix3> ja(c.jacobian_a);
  Eigen::Map<RowMatrix3> jb(c.jacobian_b);
  ja.setZero();
  jb.setZero();
  ja.topLeftCorner<2, 2>() = -to_a;
  ja.block<2, 1>(0, 2) = -to_a * perpendicular(end_b - pa);
  ja(2, 2) = -1.0;
  jb.topLeftCorner<2, 2>() = to_a;
  jb.block<2, 1>(0, 2) = to_a * perpendicular(b_lever_m);
  jb(2, 2) = 1.0;
  // Huber on the Mahalanobis distance: beyond closure_huber_sigmas a constant pull.
  const double distance = std::sqrt(std::max(0.0, residual.dot(c.closure.information * residual)));
  const double huber =
      distance <= config_.closure_huber_sigmas ? 1.0 : config_.closure_huber_sigmas / distance;
  Eigen::Map<RowMatrix3>(c.weight) = huber * c.closure.information;
  Eigen::Map<Eigen::Vector3d>(c.residual) = residual;
}

void PathSmoother::accumulate_closure_gradient(const Closure& c) noexcept {
  const Eigen::Vector3d pull =
      Eigen::Map<const RowMatrix3>(c.weight) * Eigen::Map<const Eigen::Vector3d>(c.residual);
  Eigen::Map<Eigen::Vector3d>(blocks_[c.a].gradient) +=
      Eigen::Map<const RowMatrix3>(c.jacobian_a).transpose() * pull;
  Eigen::Map<Eigen::Vector3d>(blocks_[c.b].gradient) +=
      Eigen::Map<const RowMatrix3>(c.jacobian_b).transpose() * pull;
}

void PathSmoother::add_closures_times(Vector5Member in, Vector5Member out) noexcept {
  for (std::size_t k = 0; k < closure_count_; ++k) {
    const Closure& c = closures_[k];
    const Eigen::Map<const RowMatrix3> ja(c.jacobian_a);
    const Eigen::Map<const RowMatrix3> jb(c.jacobian_b);
    const Eigen::Vector3d moved = ja * Eigen::Map<const Eigen::Vector3d>(blocks_[c.a].*in) +
                                  jb * Eigen::Map<const Eigen::Vector3d>(blocks_[c.b].*in);
    const Eigen::Vector3d weighted = Eigen::Map<const RowMatrix3>(c.weight) * moved;
    Eigen::Map<Eigen::Vector3d>(blocks_[c.a].*out) += ja.transpose() * weighted;
    Eigen::Map<Eigen::Vector3d>(blocks_[c.b].*out) += jb.transpose() * weighted;
  }
}

}  // namespace blockmap::localize
