// Plane detection's speed on one core: the first N points of the simulated usc_block run (the
// truth cloud: every return along the true trajectory), from points to the plane list.
//   build/release/tests/bench/bench_planes
// `ns_per_point` is the whole detection (samples, shapes, sections, Hough, refinement,
// merging) per input point; its growth with N shows whether the cost is linear.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/truth_cloud.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "blockmap/planes/plane_detector.hpp"

namespace blockmap::planes {
namespace {

const std::vector<Eigen::Vector3f>& city_cloud() {
  static const std::vector<Eigen::Vector3f> points = [] {
    hal::sim::SimOptions options;
    options.seed = 3;
    return hal::sim::simulate_truth_cloud(hal::sim::load_world("usc_block"),
                                          hal::config::load_robot("paper_rmp"), options)
        .points_m;
  }();
  return points;
}

void BM_DetectPlanes(benchmark::State& state, VotingMode voting) {
  const std::vector<Eigen::Vector3f>& all = city_cloud();
  const auto count = std::min(all.size(), static_cast<std::size_t>(state.range(0)));
  const std::span<const Eigen::Vector3f> points(all.data(), count);
  PlanesConfig config;
  config.voting_mode = voting;
  config.max_samples = 1 << 18;  // room for 1 M points of a city (142,000 samples)
  Arena arena(PlaneDetector::arena_budget_bytes(config));
  PlaneDetector detector;
  detector.init(arena, config);
  arena.seal();
  std::size_t planes = 0;
  for (auto _ : state) {
    detector.clear();
    detector.add_points(points);
    planes = detector.detect().size();
    benchmark::DoNotOptimize(planes);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(count));
  // An inverted rate of count * 1e-9 per iteration is nanoseconds per point.
  state.counters["ns_per_point"] = benchmark::Counter(
      static_cast<double>(count) * 1e-9,
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["points"] = static_cast<double>(count);
  state.counters["planes"] = static_cast<double>(planes);
  state.counters["samples"] = static_cast<double>(detector.stats().samples);
  state.counters["blocks"] = static_cast<double>(detector.voxels().block_count());
  state.counters["sections"] = static_cast<double>(detector.stats().sections);
  state.counters["searched"] = static_cast<double>(detector.stats().sections_searched);
  state.counters["planar"] = static_cast<double>(detector.stats().planar_samples);
  state.counters["linear"] = static_cast<double>(detector.stats().linear_samples);
  state.counters["votes"] = static_cast<double>(detector.stats().votes);
  state.counters["peaks"] = static_cast<double>(detector.stats().peaks);
  state.counters["section_planes"] = static_cast<double>(detector.stats().section_planes);
  state.counters["arena_MiB"] = static_cast<double>(arena.used_bytes()) / (1 << 20);
}

BENCHMARK_CAPTURE(BM_DetectPlanes, local_shape, VotingMode::kLocalShape)
    ->Arg(250'000)
    ->Arg(500'000)
    ->Arg(1'000'000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_DetectPlanes, every_orientation, VotingMode::kEveryOrientation)
    ->Arg(250'000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace blockmap::planes
