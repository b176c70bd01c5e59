// The rigid path's solver against Ceres (issue 54: a well-kept solver, or a hand-written one
// with the reason measured; docs/design.md, The path's solver). Both solve the same problem,
// the whole path of the synthetic drive of the localization tests: one keyframe per fix, the
// odometry's relative motion, the receiver's slow error as a Gauss-Markov process and each
// fix, weighed as localize::PathSmoother weighs them. Each iteration builds the problem from
// nothing and solves it; the counters give the heap allocations of an iteration and how far
// the two solutions lie apart. Run: scripts/bench-solvers
#include <benchmark/benchmark.h>
#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "allocation_counter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "blockmap/localize/scan_matcher.hpp"
#include "synthetic_drive.hpp"

namespace {

using blockmap::Arena;
using blockmap::localize::PathSmoother;
using blockmap::localize::PathSmootherConfig;
using blockmap::localize::Pose2;
namespace synthetic = blockmap::localize::synthetic;

// PathSmoother's floors on a term's variance, the same here.
constexpr double kMinMotionVarianceM2 = PathSmoother::kMinMotionVarianceM2;
constexpr double kMinTurnVarianceRad2 = PathSmoother::kMinTurnVarianceRad2;
constexpr double kMinBiasDecay = PathSmoother::kMinBiasDecay;

// A drive of state.range(0) keyframes: 4 Hz fixes, so a keyframe every 0.25 s.
struct Drive {
  explicit Drive(std::int64_t keyframes) {
    synthetic::DriveOptions options;
    options.duration_s = 0.25 * static_cast<double>(keyframes) + 0.1;
    samples = synthetic::drive(options);
    odometry = synthetic::calibrated_odometry(samples, options, 1e-4);
  }
  std::vector<synthetic::Sample> samples;
  std::vector<Pose2> odometry;
};

void feed(PathSmoother& smoother, const Drive& drive) {
  for (std::size_t i = 0; i < drive.samples.size(); ++i) {
    const synthetic::Sample& s = drive.samples[i];
    std::optional<Eigen::Vector2d> fix;
    if (s.has_fix) {
      fix = Eigen::Vector2d(s.fix.east_m, s.fix.north_m);
    }
    smoother.add(drive.odometry[i], fix);
  }
}

// --- The same problem for Ceres ----------------------------------------------------------

template <typename T>
T wrapped(T angle_rad) {
  using std::floor;
  const double two_pi = 2.0 * synthetic::kPi;
  return angle_rad - two_pi * floor((angle_rad + synthetic::kPi) / two_pi);
}

// The odometry's motion from keyframe a to b, in a's frame, times the square root of its
// information (diagonal: along, across, turn).
struct MotionResidual {
  Eigen::Vector3d measured;
  Eigen::Vector3d sqrt_information;
  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    using std::cos;
    using std::sin;
    const T c = cos(a[2]);
    const T s = sin(a[2]);
    const T dx = b[0] - a[0];
    const T dy = b[1] - a[1];
    residual[0] = sqrt_information.x() * (c * dx + s * dy - measured.x());
    residual[1] = sqrt_information.y() * (-s * dx + c * dy - measured.y());
    residual[2] = sqrt_information.z() * wrapped(b[2] - a[2] - measured.z());
    return true;
  }
};

// The slow error: b(i+1) = decay b(i) + w.
struct SlowErrorResidual {
  double decay;
  double sqrt_information;
  template <typename T>
  bool operator()(const T* before, const T* after, T* residual) const {
    residual[0] = sqrt_information * (after[0] - decay * before[0]);
    residual[1] = sqrt_information * (after[1] - decay * before[1]);
    return true;
  }
};

// The first keyframe's slow error: the process's own spread around zero.
struct SlowErrorPrior {
  double sqrt_information;
  template <typename T>
  bool operator()(const T* slow, T* residual) const {
    residual[0] = sqrt_information * slow[0];
    residual[1] = sqrt_information * slow[1];
    return true;
  }
};

// position + slow error = fix.
struct FixResidual {
  Eigen::Vector2d fix_m;
  double sqrt_weight;
  template <typename T>
  bool operator()(const T* pose, const T* slow, T* residual) const {
    residual[0] = sqrt_weight * (pose[0] + slow[0] - fix_m.x());
    residual[1] = sqrt_weight * (pose[1] + slow[1] - fix_m.y());
    return true;
  }
};

Eigen::Vector3d motion_sqrt_information(const PathSmootherConfig& config, const Pose2& a,
                                        const Pose2& b) {
  const Eigen::Vector3d measured = blockmap::localize::pose_in_frame_of(a, b);
  const double distance_m = std::hypot(measured.x(), measured.y());
  const double dt_s = blockmap::seconds_from_ns(b.stamp_ns - a.stamp_ns);
  const auto squared = [](double x) { return x * x; };
  return {
      1.0 / std::sqrt(squared(config.along_sigma_per_sqrt_m) * distance_m + kMinMotionVarianceM2),
      1.0 / std::sqrt(squared(config.across_sigma_per_sqrt_m) * distance_m + kMinMotionVarianceM2),
      1.0 / std::sqrt(squared(config.yaw_sigma_per_sqrt_m) * distance_m +
                      squared(config.yaw_sigma_per_sqrt_s) * dt_s + kMinTurnVarianceRad2)};
}

// The keyframes PathSmoother made (their odometry poses) and the fix of each, as Ceres
// parameter blocks started where the smoother starts: the odometry moved onto the first fix.
struct CeresPath {
  CeresPath(const PathSmoother& made, const Drive& drive) {
    for (std::size_t i = 0; i < made.keyframe_count(); ++i) {
      keyframes.push_back(made.odometry(i));
      const auto sample =
          static_cast<std::size_t>(keyframes.back().stamp_ns / synthetic::kOdometryPeriodNs) - 1;
      fixes.push_back(drive.samples[sample]);
    }
    const auto first_fix = std::find_if(fixes.begin(), fixes.end(),
                                        [](const synthetic::Sample& s) { return s.has_fix; });
    const std::size_t at = static_cast<std::size_t>(first_fix - fixes.begin());
    shift = Eigen::Vector2d(first_fix->fix.east_m - keyframes[at].x_m,
                            first_fix->fix.north_m - keyframes[at].y_m);
  }
  void start(std::vector<std::array<double, 3>>& poses,
             std::vector<std::array<double, 2>>& slow) const {
    poses.resize(keyframes.size());
    slow.assign(keyframes.size(), {0.0, 0.0});
    for (std::size_t i = 0; i < keyframes.size(); ++i) {
      poses[i] = {keyframes[i].x_m + shift.x(), keyframes[i].y_m + shift.y(), keyframes[i].yaw_rad};
    }
  }
  std::vector<Pose2> keyframes;
  std::vector<synthetic::Sample> fixes;
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();
};

void build(ceres::Problem& problem, const CeresPath& path, const PathSmootherConfig& config,
           std::vector<std::array<double, 3>>& poses, std::vector<std::array<double, 2>>& slow) {
  const double stationary = 1.0 / (config.bias_sigma_m * config.bias_sigma_m);
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SlowErrorPrior, 2, 2>(
                               new SlowErrorPrior{std::sqrt(stationary)}),
                           nullptr, slow[0].data());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const synthetic::Sample& s = path.fixes[i];
    if (s.has_fix) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<FixResidual, 2, 3, 2>(new FixResidual{
              Eigen::Vector2d(s.fix.east_m, s.fix.north_m), 1.0 / config.fix_sigma_m}),
          nullptr, poses[i].data(), slow[i].data());
    }
    if (i + 1 == poses.size()) {
      break;
    }
    const Pose2& a = path.keyframes[i];
    const Pose2& b = path.keyframes[i + 1];
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<MotionResidual, 3, 3, 3>(new MotionResidual{
            blockmap::localize::pose_in_frame_of(a, b), motion_sqrt_information(config, a, b)}),
        nullptr, poses[i].data(), poses[i + 1].data());
    const double decay =
        std::exp(-blockmap::seconds_from_ns(b.stamp_ns - a.stamp_ns) / config.bias_time_s);
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SlowErrorResidual, 2, 2, 2>(new SlowErrorResidual{
            decay, std::sqrt(stationary / std::max(1.0 - decay * decay, kMinBiasDecay))}),
        nullptr, slow[i].data(), slow[i + 1].data());
  }
}

std::uint64_t allocations() {
  return blockmap::testing::allocations_on_this_thread().calls;
}

// --- The benchmarks -----------------------------------------------------------------------

// PathSmoother: the keyframes added and the path solved (its 3 Gauss-Newton steps), in an
// arena taken before the clock starts.
void BM_PathSmoother(benchmark::State& state) {
  const Drive drive(state.range(0));
  PathSmootherConfig config;
  config.max_keyframes = static_cast<std::size_t>(state.range(0)) + 64;  // no thinning
  std::uint64_t allocated = 0;
  std::size_t keyframes = 0;
  for (auto _ : state) {
    state.PauseTiming();
    Arena arena(PathSmoother::arena_bytes(config));
    PathSmoother smoother;
    smoother.init(arena, config);
    state.ResumeTiming();
    const std::uint64_t before = allocations();
    feed(smoother, drive);
    smoother.solve();
    allocated += allocations() - before;
    keyframes = smoother.keyframe_count();
    benchmark::DoNotOptimize(smoother.pose(keyframes - 1));
  }
  state.counters["keyframes"] = static_cast<double>(keyframes);
  state.counters["allocations"] =
      static_cast<double>(allocated) / static_cast<double>(state.iterations());
  state.counters["arena_KiB"] = static_cast<double>(PathSmoother::arena_bytes(config)) / 1024.0;
}
BENCHMARK(BM_PathSmoother)->Arg(500)->Arg(2000)->Arg(8000)->Unit(benchmark::kMillisecond);

// Ceres: the same keyframes and terms, built into a Problem and solved by Levenberg-Marquardt
// with its sparse normal Cholesky (SuiteSparse), one thread, at most state.range(1) steps
// (3: PathSmoother's). `apart_m` is the largest distance between its keyframes and
// PathSmoother's, solved from the same start; `build_share` the part of the time spent
// making the Problem.
void BM_Ceres(benchmark::State& state) {
  const Drive drive(state.range(0));
  PathSmootherConfig config;
  config.max_keyframes = static_cast<std::size_t>(state.range(0)) + 64;  // no thinning
  Arena arena(PathSmoother::arena_bytes(config));
  PathSmoother smoother;
  smoother.init(arena, config);
  feed(smoother, drive);
  smoother.solve();
  const CeresPath path(smoother, drive);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.num_threads = 1;
  options.max_num_iterations = static_cast<int>(state.range(1));
  std::vector<std::array<double, 3>> poses;
  std::vector<std::array<double, 2>> slow;
  std::uint64_t allocated = 0;
  ceres::Solver::Summary summary;
  double build_s = 0.0;
  double total_s = 0.0;
  for (auto _ : state) {
    path.start(poses, slow);
    const std::uint64_t before = allocations();
    const auto start = std::chrono::steady_clock::now();
    ceres::Problem problem;
    build(problem, path, config, poses, slow);
    const auto built = std::chrono::steady_clock::now();
    ceres::Solve(options, &problem, &summary);
    const auto solved = std::chrono::steady_clock::now();
    allocated += allocations() - before;
    build_s += std::chrono::duration<double>(built - start).count();
    total_s += std::chrono::duration<double>(solved - start).count();
  }
  double apart_m = 0.0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Pose2 p = smoother.pose(i);
    apart_m = std::max(apart_m, std::hypot(poses[i][0] - p.x_m, poses[i][1] - p.y_m));
  }
  state.counters["keyframes"] = static_cast<double>(poses.size());
  state.counters["allocations"] =
      static_cast<double>(allocated) / static_cast<double>(state.iterations());
  state.counters["iterations"] = static_cast<double>(summary.iterations.size());
  state.counters["apart_m"] = apart_m;
  state.counters["build_share"] = build_s / total_s;
}
BENCHMARK(BM_Ceres)
    ->Args({500, 50})
    ->Args({2000, 50})
    ->Args({8000, 50})
    ->Args({2000, 3})
    ->Unit(benchmark::kMillisecond);

}  // namespace
