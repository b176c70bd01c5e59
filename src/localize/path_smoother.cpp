#include "blockmap/localize/path_smoother.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "path_state.hpp"

namespace blockmap::localize {
namespace {

using path_state::Jacobian2;
using path_state::Jacobian3;
using path_state::kBiasX;
using path_state::kBiasY;
using path_state::kX;
using path_state::kY;
using path_state::kYaw;
using path_state::Matrix5;
using path_state::Vector5;

// Added to every diagonal: the path without a single fix has no place of its own.
constexpr double kDamping = 1e-9;

bool positive(double value) noexcept {
  return std::isfinite(value) && value > 0.0;
}

Eigen::Map<Matrix5> matrix(double (&block)[25]) noexcept {
  return Eigen::Map<Matrix5>(block);
}

Eigen::Map<Vector5> vector(double (&block)[5]) noexcept {
  return Eigen::Map<Vector5>(block);
}

}  // namespace

std::string validate(const PathSmootherConfig& config) {
  if (config.max_keyframes < 4) {
    return "path smoother: max_keyframes must be at least 4";
  }
  if (!positive(config.keyframe_spacing_m) || !positive(config.along_sigma_per_sqrt_m) ||
      !positive(config.across_sigma_per_sqrt_m) || !positive(config.yaw_sigma_per_sqrt_m) ||
      !positive(config.yaw_sigma_per_sqrt_s) || !positive(config.matched_across_sigma_per_sqrt_m) ||
      !positive(config.matched_yaw_sigma_per_sqrt_m)) {
    return "path smoother: keyframe_spacing_m and the motion's sigmas must be positive";
  }
  if (!(config.unlearnt_yaw_rate_bias_sigma_radps >= 0.0) ||
      !positive(config.unlearnt_yaw_rate_bias_time_s)) {
    return "path smoother: unlearnt_yaw_rate_bias_sigma_radps must not be negative and "
           "unlearnt_yaw_rate_bias_time_s must be positive";
  }
  if (!positive(config.bias_sigma_m) || !positive(config.bias_time_s) ||
      !positive(config.fix_sigma_m) || !positive(config.rtk_fixed_sigma_m) ||
      !positive(config.rtk_float_sigma_m)) {
    return "path smoother: bias_sigma_m, bias_time_s, fix_sigma_m, rtk_fixed_sigma_m and "
           "rtk_float_sigma_m must be positive";
  }
  if (config.iterations == 0) {
    return "path smoother: iterations must be at least 1";
  }
  if (config.max_ties > 0 &&
      (!positive(config.tie_offset_sigma_m) || !positive(config.tie_angle_sigma_deg) ||
       !positive(config.tie_huber_sigmas) || !positive(config.tie_gate_deg) ||
       config.cg_iterations == 0)) {
    return "path smoother: tie_offset_sigma_m, tie_angle_sigma_deg, tie_huber_sigmas and "
           "tie_gate_deg must be positive and cg_iterations at least 1 (or max_ties = 0)";
  }
  if (config.max_closures > 0 &&
      (!positive(config.closure_huber_sigmas) || config.cg_iterations == 0)) {
    return "path smoother: closure_huber_sigmas must be positive and cg_iterations at least 1 "
           "(or max_closures = 0)";
  }
  return {};
}

std::size_t PathSmoother::arena_bytes(const PathSmootherConfig& config) noexcept {
  constexpr std::size_t kSlack = 2 * alignof(std::max_align_t);
  return config.max_keyframes * (sizeof(Keyframe) + sizeof(Blocks)) +
         config.max_ties * sizeof(Tie) + config.max_closures * sizeof(Closure) + 4 * kSlack;
}

void PathSmoother::init(Arena& arena, const PathSmootherConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), problem.c_str());
  config_ = config;
  keyframes_ = arena.allocate_array<Keyframe>(config.max_keyframes, "localize.path_keyframes");
  blocks_ = arena.allocate_array<Blocks>(config.max_keyframes, "localize.path_normal_equations");
  ties_ = arena.allocate_array<Tie>(config.max_ties, "localize.path_ties");
  closures_ = arena.allocate_array<Closure>(config.max_closures, "localize.path_closures");
  count_ = 0;
  tie_count_ = 0;
  closure_count_ = 0;
  first_information_[0] = first_information_[1] = 0.0;
  placings_carry_offset_ = false;
  dead_reckoned_m_ = 0.0;
  dead_reckoned_s_ = 0.0;
  unlearnt_turn_variance_rad2_ = 0.0;
  matched_any_ = false;
  noted_dead_reckoning_ = false;
  counters_ = {};
}

std::size_t PathSmoother::memory_bytes() const noexcept {
  return keyframes_.size_bytes() + blocks_.size_bytes() + ties_.size_bytes() +
         closures_.size_bytes();
}

void PathSmoother::FixMean::merge(double east, double north, double more_weight) noexcept {
  const double total = weight + more_weight;
  east_m += (east - east_m) * more_weight / total;
  north_m += (north - north_m) * more_weight / total;
  weight = total;
}

void PathSmoother::add(const Pose2& odometry, const Pose2& drawn,
                       const std::optional<Eigen::Vector2d>& fix_m, double fix_sigma_scale,
                       GpsCorrection correction) noexcept {
  if (refuses(odometry)) {
    return;
  }
  if (fix_m.has_value()) {
    Keyframe& keyframe = keyframe_placed_at(odometry, drawn, *fix_m);
    double sigma_m = config_.fix_sigma_m * std::max(fix_sigma_scale, 1e-3);
    FixMean* into = &keyframe.code_fixes;
    if (carrier_phase(correction)) {
      sigma_m = correction == GpsCorrection::kRtkFixed ? config_.rtk_fixed_sigma_m
                                                       : config_.rtk_float_sigma_m;
      into = &keyframe.carrier_fixes;
    }
    into->merge(fix_m->x(), fix_m->y(), 1.0 / (sigma_m * sigma_m));
    ++counters_.fixes;
    return;
  }
  if (count_ == 0) {
    append(odometry, drawn);
    return;
  }
  const Pose2& last = keyframes_[count_ - 1].odometry;
  if (std::hypot(odometry.x_m - last.x_m, odometry.y_m - last.y_m) >= config_.keyframe_spacing_m) {
    append(odometry, drawn);
  }
}

void PathSmoother::Placings::merge(const Eigen::Vector2d& position_m,
                                   const Eigen::Matrix2d& more) noexcept {
  information[0] += more(0, 0);
  information[1] += more(0, 1);
  information[2] += more(1, 1);
  const Eigen::Vector2d added = more * position_m;
  moment[0] += added.x();
  moment[1] += added.y();
}

void PathSmoother::Placings::merge_moved(const Placings& other,
                                         const Eigen::Vector2d& by_m) noexcept {
  // m = L p for each placed p: moving them by -by takes L by off.
  for (int k = 0; k < 3; ++k) {
    information[k] += other.information[k];
  }
  moment[0] +=
      other.moment[0] - (other.information[0] * by_m.x() + other.information[1] * by_m.y());
  moment[1] +=
      other.moment[1] - (other.information[1] * by_m.x() + other.information[2] * by_m.y());
}

void PathSmoother::place(const Pose2& odometry, const Pose2& drawn,
                         const Eigen::Vector2d& position_m,
                         const Eigen::Matrix2d& information) noexcept {
  if (refuses(odometry)) {
    return;
  }
  Keyframe& keyframe = keyframe_placed_at(odometry, drawn, position_m);
  keyframe.placings.merge(position_m, information);
  ++counters_.placings;
}

void PathSmoother::hold_first(double sigma_m, double yaw_sigma_rad) noexcept {
  first_information_[0] = 1.0 / (sigma_m * sigma_m + kMinMotionVarianceM2);
  first_information_[1] = 1.0 / (yaw_sigma_rad * yaw_sigma_rad + kMinTurnVarianceRad2);
}

void PathSmoother::carry_map_offset(double sigma_m, double time_s) noexcept {
  placings_carry_offset_ = true;
  config_.bias_sigma_m = sigma_m;
  config_.bias_time_s = time_s;
}

Eigen::Vector2d PathSmoother::slow_error(const Pose2& odometry) const noexcept {
  BLOCKMAP_CHECK_MSG(count_ > 0, "slow_error() before the first keyframe");
  const Keyframe& keyframe = keyframes_[keyframe_nearest(odometry.stamp_ns)];
  return {keyframe.state[kBiasX], keyframe.state[kBiasY]};
}

bool PathSmoother::refuses(const Pose2& odometry) noexcept {
  const bool older = count_ > 0 && odometry.stamp_ns < keyframes_[count_ - 1].odometry.stamp_ns;
  counters_.refused += older ? 1 : 0;
  return older;
}

PathSmoother::Keyframe& PathSmoother::keyframe_placed_at(
    const Pose2& odometry, const Pose2& drawn, const Eigen::Vector2d& position_m) noexcept {
  const bool same_time =
      count_ > 0 && odometry.stamp_ns == keyframes_[count_ - 1].odometry.stamp_ns;
  if (!same_time) {
    append(odometry, drawn);
  }
  Keyframe& keyframe = keyframes_[count_ - 1];
  if (counters_.fixes == 0 && counters_.placings == 0 && !holds_first()) {
    // The first fix says where the path is: every keyframe so far moves with it, so that
    // Gauss-Newton starts near the answer.
    const double dx = position_m.x() - keyframe.state[kX];
    const double dy = position_m.y() - keyframe.state[kY];
    for (std::size_t i = 0; i < count_; ++i) {
      keyframes_[i].state[kX] += dx;
      keyframes_[i].state[kY] += dy;
    }
  }
  return keyframe;
}

void PathSmoother::append(const Pose2& odometry, const Pose2& drawn) noexcept {
  if (count_ == keyframes_.size()) {
    thin();
  }
  Keyframe& next = keyframes_[count_];
  next = Keyframe{};
  next.odometry = odometry;
  next.drawn = drawn;
  next.dead_reckoned_m = dead_reckoned_m_;
  next.dead_reckoned_s = dead_reckoned_s_;
  next.unlearnt_turn_variance_rad2 = unlearnt_turn_variance_rad2_;
  dead_reckoned_m_ = 0.0;
  dead_reckoned_s_ = 0.0;
  unlearnt_turn_variance_rad2_ = 0.0;
  if (count_ == 0) {
    // Where the caller drew it: the odometry's frame says nothing about the local frame.
    next.state[kX] = drawn.x_m;
    next.state[kY] = drawn.y_m;
    next.state[kYaw] = drawn.yaw_rad;
  } else {
    // Where the odometry puts it from the keyframe before, as solved.
    const Keyframe& before = keyframes_[count_ - 1];
    const Eigen::Vector3d motion = pose_in_frame_of(before.odometry, odometry);
    const double c = std::cos(before.state[kYaw]);
    const double s = std::sin(before.state[kYaw]);
    next.state[kX] = before.state[kX] + c * motion.x() - s * motion.y();
    next.state[kY] = before.state[kY] + s * motion.x() + c * motion.y();
    next.state[kYaw] = wrap_angle(before.state[kYaw] + motion.z());
    const double decay = std::exp(-seconds_from_ns(odometry.stamp_ns - before.odometry.stamp_ns) /
                                  config_.bias_time_s);
    next.state[kBiasX] = decay * before.state[kBiasX];
    next.state[kBiasY] = decay * before.state[kBiasY];
  }
  ++count_;
  ++counters_.keyframes_added;
}

void PathSmoother::thin() noexcept {
  // Odd keyframes go into the even one before them; the newest stays, so that the path ends
  // where the odometry last was. A merged fix is moved by the solved motion between the two.
  std::size_t kept = 0;
  for (std::size_t i = 0; i < count_; ++i) {
    const bool merged = i % 2 == 1 && i + 1 < count_;
    if (!merged) {
      keyframes_[kept++] = keyframes_[i];
      continue;
    }
    Keyframe& into = keyframes_[kept - 1];
    const Keyframe& from = keyframes_[i];
    keyframes_[i + 1].dead_reckoned_m += from.dead_reckoned_m;  // now from `into` on
    keyframes_[i + 1].dead_reckoned_s += from.dead_reckoned_s;
    keyframes_[i + 1].unlearnt_turn_variance_rad2 += from.unlearnt_turn_variance_rad2;
    const double dx_m = from.state[kX] - into.state[kX];
    const double dy_m = from.state[kY] - into.state[kY];
    for (const auto member : {&Keyframe::code_fixes, &Keyframe::carrier_fixes}) {
      const FixMean& fixes = from.*member;
      if (fixes.weight > 0.0) {
        (into.*member).merge(fixes.east_m - dx_m, fixes.north_m - dy_m, fixes.weight);
      }
    }
    into.placings.merge_moved(from.placings, Eigen::Vector2d(dx_m, dy_m));
  }
  count_ = kept;
  ++counters_.thinnings;
}

void PathSmoother::note_dead_reckoning(double distance_m, double duration_s,
                                       double matched_s) noexcept {
  noted_dead_reckoning_ = true;
  dead_reckoned_m_ += distance_m;
  dead_reckoned_s_ += duration_s;
  matched_any_ = matched_any_ || matched_s > 0.0;
  if (!matched_any_) {
    const double sigma_radps = config_.unlearnt_yaw_rate_bias_sigma_radps;
    unlearnt_turn_variance_rad2_ +=
        sigma_radps * sigma_radps * config_.unlearnt_yaw_rate_bias_time_s * duration_s;
  }
}

void PathSmoother::accumulate_motion(std::size_t i) noexcept {
  const Keyframe& a = keyframes_[i];
  const Keyframe& b = keyframes_[i + 1];
  const Eigen::Vector3d measured = pose_in_frame_of(a.odometry, b.odometry);
  const double distance_m = std::hypot(measured.x(), measured.y());
  const double dt_s = seconds_from_ns(b.odometry.stamp_ns - a.odometry.stamp_ns);
  const double c = std::cos(a.state[kYaw]);
  const double s = std::sin(a.state[kYaw]);
  const double dx = b.state[kX] - a.state[kX];
  const double dy = b.state[kY] - a.state[kY];
  const Eigen::Vector3d residual(c * dx + s * dy - measured.x(), -s * dx + c * dy - measured.y(),
                                 wrap_angle(b.state[kYaw] - a.state[kYaw] - measured.z()));
  // Across the way and in the turn, the matched part of the motion is weighed as matched,
  // and the turn's per-second noise (a gyroscope bias) counts over the time the odometry
  // carried alone: all of the motion is the odometry's when the caller never says.
  const double alone_m =
      noted_dead_reckoning_ ? std::min(distance_m, b.dead_reckoned_m) : distance_m;
  const double matched_m = distance_m - alone_m;
  const double alone_s = noted_dead_reckoning_ ? std::min(dt_s, b.dead_reckoned_s) : dt_s;
  const auto squared = [](double x) { return x * x; };
  const Eigen::Vector3d information(
      1.0 / (squared(config_.along_sigma_per_sqrt_m) * distance_m + kMinMotionVarianceM2),
      1.0 / (squared(config_.across_sigma_per_sqrt_m) * alone_m +
             squared(config_.matched_across_sigma_per_sqrt_m) * matched_m + kMinMotionVarianceM2),
      1.0 / (squared(config_.yaw_sigma_per_sqrt_m) * alone_m +
             squared(config_.matched_yaw_sigma_per_sqrt_m) * matched_m +
             squared(config_.yaw_sigma_per_sqrt_s) * alone_s + b.unlearnt_turn_variance_rad2 +
             kMinTurnVarianceRad2));
  Jacobian3 ja = Jacobian3::Zero();
  Jacobian3 jb = Jacobian3::Zero();
  ja(0, kX) = -c;
  ja(0, kY) = -s;
  ja(1, kX) = s;
  ja(1, kY) = -c;
  ja(0, kYaw) = -s * dx + c * dy;
  ja(1, kYaw) = -c * dx - s * dy;
  ja(2, kYaw) = -1.0;
  jb(0, kX) = c;
  jb(0, kY) = s;
  jb(1, kX) = -s;
  jb(1, kY) = c;
  jb(2, kYaw) = 1.0;
  const Eigen::DiagonalMatrix<double, 3> omega(information);
  matrix(blocks_[i].diagonal) += ja.transpose() * omega * ja;
  matrix(blocks_[i + 1].diagonal) += jb.transpose() * omega * jb;
  matrix(blocks_[i].upper) += ja.transpose() * omega * jb;
  vector(blocks_[i].gradient) += ja.transpose() * omega * residual;
  vector(blocks_[i + 1].gradient) += jb.transpose() * omega * residual;
}

void PathSmoother::accumulate_receiver(std::size_t i) noexcept {
  const double stationary = 1.0 / (config_.bias_sigma_m * config_.bias_sigma_m);
  if (i == 0) {
    // The first keyframe's slow error: the process's own spread.
    for (const int axis : {kBiasX, kBiasY}) {
      matrix(blocks_[0].diagonal)(axis, axis) += stationary;
      vector(blocks_[0].gradient)(axis) += stationary * keyframes_[0].state[axis];
    }
  }
  if (i + 1 == count_) {
    return;
  }
  // b(i+1) = a b(i) + w, var(w) = sigma^2 (1 - a^2).
  const Keyframe& a = keyframes_[i];
  const Keyframe& b = keyframes_[i + 1];
  const double decay =
      std::exp(-seconds_from_ns(b.odometry.stamp_ns - a.odometry.stamp_ns) / config_.bias_time_s);
  const double information = stationary / std::max(1.0 - decay * decay, kMinBiasDecay);
  for (const int axis : {kBiasX, kBiasY}) {
    const double residual = b.state[axis] - decay * a.state[axis];
    matrix(blocks_[i].diagonal)(axis, axis) += information * decay * decay;
    matrix(blocks_[i + 1].diagonal)(axis, axis) += information;
    matrix(blocks_[i].upper)(axis, axis) += -information * decay;
    vector(blocks_[i].gradient)(axis) += -information * decay * residual;
    vector(blocks_[i + 1].gradient)(axis) += information * residual;
  }
}

void PathSmoother::accumulate_fix(std::size_t i) noexcept {
  accumulate_fix(i, keyframes_[i].code_fixes, true);
  accumulate_fix(i, keyframes_[i].carrier_fixes, false);
  accumulate_placings(i);
}

void PathSmoother::accumulate_placings(std::size_t i) noexcept {
  // 1/2 q' L q - m' q with q the position (plus the map's offset when carried): the
  // placings' sum, whose gradient is L q - m.
  const Placings& placings = keyframes_[i].placings;
  const Eigen::Matrix2d information{{placings.information[0], placings.information[1]},
                                    {placings.information[1], placings.information[2]}};
  const Keyframe& keyframe = keyframes_[i];
  Eigen::Vector2d position(keyframe.state[kX], keyframe.state[kY]);
  if (placings_carry_offset_) {
    position += Eigen::Vector2d(keyframe.state[kBiasX], keyframe.state[kBiasY]);
  }
  const Eigen::Vector2d gradient =
      information * position - Eigen::Vector2d(placings.moment[0], placings.moment[1]);
  matrix(blocks_[i].diagonal).block<2, 2>(kX, kX) += information;
  vector(blocks_[i].gradient).segment<2>(kX) += gradient;
  if (placings_carry_offset_) {
    matrix(blocks_[i].diagonal).block<2, 2>(kBiasX, kBiasX) += information;
    matrix(blocks_[i].diagonal).block<2, 2>(kX, kBiasX) += information;
    matrix(blocks_[i].diagonal).block<2, 2>(kBiasX, kX) += information;
    vector(blocks_[i].gradient).segment<2>(kBiasX) += gradient;
  }
}

void PathSmoother::accumulate_first_hold() noexcept {
  // The first keyframe's pose = where it was drawn.
  const Keyframe& first = keyframes_[0];
  const double residual[3] = {first.state[kX] - first.drawn.x_m, first.state[kY] - first.drawn.y_m,
                              wrap_angle(first.state[kYaw] - first.drawn.yaw_rad)};
  for (const int axis : {kX, kY, kYaw}) {
    const double information = first_information_[axis == kYaw ? 1 : 0];
    matrix(blocks_[0].diagonal)(axis, axis) += information;
    vector(blocks_[0].gradient)(axis) += information * residual[axis];
  }
}

void PathSmoother::accumulate_fix(std::size_t i, const FixMean& fixes, bool slow_error) noexcept {
  if (fixes.weight <= 0.0) {
    return;
  }
  // position (+ slow error) = fix.
  const Keyframe& keyframe = keyframes_[i];
  const double bias = slow_error ? 1.0 : 0.0;
  const Eigen::Vector2d residual(
      keyframe.state[kX] + bias * keyframe.state[kBiasX] - fixes.east_m,
      keyframe.state[kY] + bias * keyframe.state[kBiasY] - fixes.north_m);
  Jacobian2 j = Jacobian2::Zero();
  j(0, kX) = 1.0;
  j(0, kBiasX) = bias;
  j(1, kY) = 1.0;
  j(1, kBiasY) = bias;
  matrix(blocks_[i].diagonal) += fixes.weight * j.transpose() * j;
  vector(blocks_[i].gradient) += fixes.weight * j.transpose() * residual;
}

bool PathSmoother::factor_band() noexcept {
  // Block Cholesky along the path: S(i) = D(i) - X(i-1)' S(i-1) X(i-1), X(i) = S(i)^-1 U(i).
  // The band is then M' S M, with M the identity and X(i) right of the diagonal.
  for (std::size_t i = 0; i < count_; ++i) {
    Matrix5 s = matrix(blocks_[i].diagonal);
    if (i > 0) {
      const Eigen::Map<Matrix5> x_before = matrix(blocks_[i - 1].upper);
      const Eigen::Map<Matrix5> l_before = matrix(blocks_[i - 1].diagonal);
      const Matrix5 root = l_before.transpose() * x_before;  // S = L L'
      s.noalias() -= root.transpose() * root;
    }
    const Eigen::LLT<Matrix5> factor(s);
    if (factor.info() != Eigen::Success) {
      return false;
    }
    matrix(blocks_[i].upper) = factor.solve(matrix(blocks_[i].upper));
    matrix(blocks_[i].diagonal) = factor.matrixL();
  }
  return true;
}

void PathSmoother::solve_band(Vector5Member in, Vector5Member out) noexcept {
  // M' u = in forward (u(i) = in(i) - X(i-1)' u(i-1)), then M step = S^-1 u back.
  Vector5 u_before = Vector5::Zero();
  for (std::size_t i = 0; i < count_; ++i) {
    Vector5 u = vector(blocks_[i].*in);
    if (i > 0) {
      u.noalias() -= matrix(blocks_[i - 1].upper).transpose() * u_before;
    }
    u_before = u;
    const Eigen::Map<Matrix5> l = matrix(blocks_[i].diagonal);
    const auto lower = l.triangularView<Eigen::Lower>();
    Vector5 w = lower.solve(u);
    lower.transpose().solveInPlace(w);
    vector(blocks_[i].*out) = w;
  }
  for (std::size_t i = count_ - 1; i-- > 0;) {
    vector(blocks_[i].*out).noalias() -= matrix(blocks_[i].upper) * vector(blocks_[i + 1].*out);
  }
}

void PathSmoother::multiply_band(Vector5Member in, Vector5Member out) noexcept {
  // M' (S (M in)), one pass: t(i) = S(i) (in(i) + X(i) in(i+1)); out(i) = t(i) + X(i-1)' t(i-1).
  Vector5 t_before = Vector5::Zero();
  for (std::size_t i = 0; i < count_; ++i) {
    Vector5 m = vector(blocks_[i].*in);
    if (i + 1 < count_) {
      m.noalias() += matrix(blocks_[i].upper) * vector(blocks_[i + 1].*in);
    }
    const Eigen::Map<Matrix5> l = matrix(blocks_[i].diagonal);
    const Vector5 root = l.triangularView<Eigen::Lower>().transpose() * m;
    const Vector5 t = l.triangularView<Eigen::Lower>() * root;
    Vector5 result = t;
    if (i > 0) {
      result.noalias() += matrix(blocks_[i - 1].upper).transpose() * t_before;
    }
    vector(blocks_[i].*out) = result;
    t_before = t;
  }
}

void PathSmoother::add_ties_times(Vector5Member in, Vector5Member out) noexcept {
  for (std::size_t t = 0; t < tie_count_; ++t) {
    const Tie& tie = ties_[t];
    for (int r = 0; r < 2; ++r) {
      double along = 0.0;
      for (int c = 0; c < 3; ++c) {
        along += tie.jacobian_a[3 * r + c] * (blocks_[tie.a].*in)[c] +
                 tie.jacobian_b[3 * r + c] * (blocks_[tie.b].*in)[c];
      }
      const double weighted = tie.weight[r] * along;
      for (int c = 0; c < 3; ++c) {
        (blocks_[tie.a].*out)[c] += tie.jacobian_a[3 * r + c] * weighted;
        (blocks_[tie.b].*out)[c] += tie.jacobian_b[3 * r + c] * weighted;
      }
    }
  }
}

double PathSmoother::dot(Vector5Member a, Vector5Member b) const noexcept {
  double sum = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    for (int k = 0; k < 5; ++k) {
      sum += (blocks_[i].*a)[k] * (blocks_[i].*b)[k];
    }
  }
  return sum;
}

bool PathSmoother::solve_step() noexcept {
  // The right-hand side, -gradient, in place of the gradient: the residual of step 0.
  constexpr Vector5Member kResidual = &Blocks::gradient;
  for (std::size_t i = 0; i < count_; ++i) {
    vector(blocks_[i].gradient) *= -1.0;
  }
  if (!factor_band()) {
    return false;
  }
  if (tie_count_ == 0 && closure_count_ == 0) {
    solve_band(kResidual, &Blocks::step);
    return true;
  }
  // Conjugate gradients on (band + ties) step = -gradient, from step 0, the band's factors
  // as the preconditioner. Stops when r' z has fallen by kTolerance (the step to about six
  // digits; much less is below rounding and never reached) or after cg_iterations. The
  // preconditioned residual z is used up (into the direction) before the product is made.
  constexpr double kTolerance = 1e-12;
  constexpr Vector5Member kPreconditioned = &Blocks::work;
  constexpr Vector5Member kProduct = &Blocks::work;
  for (std::size_t i = 0; i < count_; ++i) {
    vector(blocks_[i].step).setZero();
  }
  solve_band(kResidual, kPreconditioned);
  double rz = dot(kResidual, kPreconditioned);
  for (std::size_t i = 0; i < count_; ++i) {
    vector(blocks_[i].direction) = vector(blocks_[i].*kPreconditioned);
  }
  const double rz_first = rz;
  for (std::uint32_t k = 0; k < config_.cg_iterations && rz > kTolerance * rz_first; ++k) {
    ++counters_.cg_steps;
    multiply_band(&Blocks::direction, kProduct);
    add_ties_times(&Blocks::direction, kProduct);
    add_closures_times(&Blocks::direction, kProduct);
    const double curvature = dot(&Blocks::direction, kProduct);
    if (!(curvature > 0.0)) {
      break;
    }
    const double alpha = rz / curvature;
    for (std::size_t i = 0; i < count_; ++i) {
      vector(blocks_[i].step) += alpha * vector(blocks_[i].direction);
      vector(blocks_[i].*kResidual) -= alpha * vector(blocks_[i].*kProduct);
    }
    solve_band(kResidual, kPreconditioned);
    const double rz_next = dot(kResidual, kPreconditioned);
    const double beta = rz_next / rz;
    rz = rz_next;
    for (std::size_t i = 0; i < count_; ++i) {
      vector(blocks_[i].direction) =
          vector(blocks_[i].*kPreconditioned) + beta * vector(blocks_[i].direction);
    }
  }
  return true;
}

void PathSmoother::solve() noexcept {
  if (count_ < 2) {
    return;
  }
  ++counters_.solves;
  for (std::uint32_t iteration = 0; iteration < config_.iterations; ++iteration) {
    for (std::size_t i = 0; i < count_; ++i) {
      blocks_[i] = Blocks{};
      matrix(blocks_[i].diagonal).diagonal().array() += kDamping;
    }
    if (holds_first()) {
      accumulate_first_hold();
    }
    for (std::size_t i = 0; i < count_; ++i) {
      accumulate_fix(i);
      accumulate_receiver(i);
      if (i + 1 < count_) {
        accumulate_motion(i);
      }
    }
    for (std::size_t t = 0; t < tie_count_; ++t) {
      linearize_tie(ties_[t]);
      accumulate_tie_gradient(ties_[t]);
    }
    for (std::size_t c = 0; c < closure_count_; ++c) {
      linearize_closure(closures_[c]);
      accumulate_closure_gradient(closures_[c]);
    }
    if (!solve_step()) {
      return;
    }
    for (std::size_t i = 0; i < count_; ++i) {
      for (int k = 0; k < 5; ++k) {
        keyframes_[i].state[k] += blocks_[i].step[k];
      }
      keyframes_[i].state[kYaw] = wrap_angle(keyframes_[i].state[kYaw]);
    }
  }
}

Pose2 PathSmoother::pose(std::size_t i) const noexcept {
  BLOCKMAP_CHECK(i < count_);
  const Keyframe& k = keyframes_[i];
  return Pose2{k.odometry.stamp_ns, k.state[kX], k.state[kY], k.state[kYaw]};
}

const Pose2& PathSmoother::drawn(std::size_t i) const noexcept {
  BLOCKMAP_CHECK(i < count_);
  return keyframes_[i].drawn;
}

const Pose2& PathSmoother::odometry(std::size_t i) const noexcept {
  BLOCKMAP_CHECK(i < count_);
  return keyframes_[i].odometry;
}

PlanarCorrection PathSmoother::correction(std::size_t i) const noexcept {
  return motion_between(drawn(i), pose(i));
}

Pose2 PathSmoother::pose_at(TimestampNs stamp_ns) const noexcept {
  BLOCKMAP_CHECK_MSG(count_ > 0, "pose_at() before the first keyframe");
  const auto first = keyframes_.begin();
  const auto last = first + static_cast<std::ptrdiff_t>(count_);
  const auto after = std::upper_bound(first, last, stamp_ns, [](TimestampNs t, const Keyframe& k) {
    return t < k.odometry.stamp_ns;
  });
  if (after == first) {
    return pose(0);
  }
  if (after == last) {
    Pose2 end = pose(count_ - 1);
    end.stamp_ns = stamp_ns;
    return end;
  }
  const Pose2 a = pose(static_cast<std::size_t>(after - first) - 1);
  const Pose2 b = pose(static_cast<std::size_t>(after - first));
  const double f =
      static_cast<double>(stamp_ns - a.stamp_ns) / static_cast<double>(b.stamp_ns - a.stamp_ns);
  return Pose2{stamp_ns, a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m),
               wrap_angle(a.yaw_rad + f * wrap_angle(b.yaw_rad - a.yaw_rad))};
}

}  // namespace blockmap::localize
