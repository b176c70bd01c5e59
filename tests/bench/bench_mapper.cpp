// The whole mapper over a recorded minute of the simulated robot (usc_block): odometry, GPS and
// both lasers through the particle filter, scan projection, the sliding window, the Hough
// planes and the registry. Reported per run:
//   real_time_x      seconds of data mapped per second of this core
//   points_per_s     laser points projected and inserted per second
//   step_p50_us / step_p99_us   the pipeline's step after each message (a scan's projection
//                               and insertion happen in the step after the odometry that
//                               covers it); step_max_ms is the longest, an extraction
//   extract_ms       mean time of one plane extraction (detect + registry): a scan's points
//                    reach the plane list at the next extraction, at most extract_every_s on
// Arguments: window tiles across (5, 7, 9, 11), the pose source (0 filter, 1 true poses), 1 to
// run without the rigid path (the default solves it with the filter's poses), and 1 for
// config/far_reach.toml's window: a core of 7 tiles whose ring beyond leaves early when the
// pool runs low, and ranges to 60 m.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "recorded_mapper_inputs.hpp"

namespace blockmap::pipeline {
namespace {

const testing::RecordedMapperInputs& minute_of_usc_block() {
  static const testing::RecordedMapperInputs inputs("usc_block", 60.0);
  return inputs;
}

double percentile(std::vector<double>& values, double fraction) {
  if (values.empty()) {
    return 0.0;
  }
  const auto k = static_cast<std::size_t>(fraction * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

void BM_MapperMinute(benchmark::State& state) {
  const testing::RecordedMapperInputs& inputs = minute_of_usc_block();
  MapperConfig config = inputs.config;
  config.window.tiles_across = static_cast<std::uint32_t>(state.range(0));
  config.pose_source = state.range(1) == 0 ? PoseSource::kLocalizer : PoseSource::kExternal;
  // The third argument 1: without the rigid path (on by default with the filter's poses).
  if (state.range(2) == 1) {
    config.rigid_path = RigidPath::kOff;
  }
  if (state.range(3) == 1) {
    config.window.core_tiles_across = 7;
    config.projection.max_range_m = 60.0;
  }
  std::unique_ptr<Mapper> mapper;
  std::vector<double> step_us;
  step_us.reserve(inputs.events.size() + 16);
  double extract_s = 0.0;
  std::uint64_t points = 0;
  std::uint64_t extractions = 0;
  for (auto _ : state) {
    state.PauseTiming();
    mapper = std::make_unique<Mapper>();
    Arena arena(Mapper::arena_bytes(config));
    mapper->init(arena, config);
    arena.seal();
    step_us.clear();
    state.ResumeTiming();
    inputs.feed(*mapper, [&](bool /*after_scan*/) {
      const auto start = std::chrono::steady_clock::now();
      const std::uint64_t before = mapper->counters().extractions;
      while (mapper->step()) {
      }
      const double s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      step_us.push_back(s * 1e6);
      if (mapper->counters().extractions != before) {
        extract_s += s;
      }
    });
    points += mapper->counters().points;
    extractions += mapper->counters().extractions;
    state.PauseTiming();
    mapper.reset();
    state.ResumeTiming();
  }
  const auto runs = static_cast<double>(state.iterations());
  state.counters["real_time_x"] =
      benchmark::Counter(inputs.data_s * runs, benchmark::Counter::kIsRate);
  state.counters["points_per_s"] =
      benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
  state.counters["step_p50_us"] = percentile(step_us, 0.50);
  state.counters["step_p99_us"] = percentile(step_us, 0.99);
  state.counters["step_max_ms"] =
      step_us.empty() ? 0.0 : 1e-3 * *std::max_element(step_us.begin(), step_us.end());
  state.counters["extract_ms"] =
      extractions > 0 ? 1e3 * extract_s / static_cast<double>(extractions) : 0.0;
}
BENCHMARK(BM_MapperMinute)
    ->ArgsProduct({{5, 7, 9}, {0, 1}, {0}, {0}})
    ->Args({7, 0, 1, 0})
    ->Args({11, 0, 0, 1})
    ->Args({11, 1, 0, 1})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

}  // namespace
}  // namespace blockmap::pipeline
