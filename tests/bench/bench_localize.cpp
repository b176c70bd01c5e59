// Localization's speed on one core: one odometry prediction and one GPS update for N
// particles (the figure: a predict + update step for 1,000 particles), and the cost
// per particle. Run: build/release/tests/bench/bench_localize
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>

#include "blockmap/core/arena.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "synthetic_drive.hpp"

namespace {

using blockmap::Arena;
using blockmap::TimestampNs;
using blockmap::localize::GpsObservation;
using blockmap::localize::LocalizeConfig;
using blockmap::localize::ParticleFilter;

// A filter of state.range(0) particles, started at the origin.
struct StartedFilter {
  explicit StartedFilter(std::int64_t particles)
      : config(config_for(particles)), arena(ParticleFilter::arena_bytes(config)) {
    filter.init(arena, config);
    arena.seal();
    static_cast<void>(
        filter.update(GpsObservation{0, 0.0, 0.0, 0.9, blockmap::localize::GpsCorrection::kNone}));
  }
  static LocalizeConfig config_for(std::int64_t particles) {
    LocalizeConfig c;
    c.particle_count = static_cast<std::size_t>(particles);
    return c;
  }
  void report(benchmark::State& state) const {
    state.counters["ns_per_particle"] = benchmark::Counter(
        static_cast<double>(state.iterations()) * static_cast<double>(config.particle_count),
        benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.counters["resamplings"] = static_cast<double>(filter.counters().resamplings);
  }
  LocalizeConfig config;
  Arena arena;
  ParticleFilter filter;
};

void BM_PredictAndUpdate(benchmark::State& state) {
  StartedFilter started(state.range(0));
  ParticleFilter& filter = started.filter;
  // A straight drive east at 1.2 m/s with a gentle weave; one step is 10 ms of odometry and
  // one fix (a real run has 25 predictions per fix: this times the heavier mix).
  TimestampNs stamp = 0;
  std::int64_t k = 0;
  for (auto _ : state) {
    stamp += 10'000'000;
    ++k;
    filter.predict(stamp, 0.012, 0.05 * std::sin(0.01 * static_cast<double>(k)));
    const double x = 0.012 * static_cast<double>(k);
    benchmark::DoNotOptimize(
        filter.update(GpsObservation{stamp, x, 0.5 * std::sin(0.003 * static_cast<double>(k)), 0.9,
                                     blockmap::localize::GpsCorrection::kNone}));
  }
  started.report(state);
}
BENCHMARK(BM_PredictAndUpdate)
    ->Arg(250)
    ->Arg(1000)
    ->Arg(2000)
    ->Arg(4000)
    ->Unit(benchmark::kMicrosecond);

void BM_Predict(benchmark::State& state) {
  StartedFilter started(state.range(0));
  TimestampNs stamp = 0;
  for (auto _ : state) {
    stamp += 10'000'000;
    started.filter.predict(stamp, 0.012, 0.01);
  }
  started.report(state);
}
BENCHMARK(BM_Predict)->Arg(1000)->Unit(benchmark::kMicrosecond);

// Accuracy against the particle count, on the tests' synthetic drive (tests/support): the
// curve that justifies the default. Means over drives and filter seeds 1-10, in metres and
// degrees, scored after 60 s; the time is ten 300 s drives.
void BM_AccuracyVsParticles(benchmark::State& state) {
  namespace synthetic = blockmap::localize::synthetic;
  constexpr int kSeeds = 10;
  synthetic::RunErrors mean;
  for (auto _ : state) {
    mean = synthetic::RunErrors{};
    for (int seed = 1; seed <= kSeeds; ++seed) {
      synthetic::DriveOptions options;
      options.seed = static_cast<std::uint64_t>(seed);
      LocalizeConfig config;
      config.particle_count = static_cast<std::size_t>(state.range(0));
      config.seed = static_cast<std::uint64_t>(seed);
      Arena arena(ParticleFilter::arena_bytes(config));
      ParticleFilter filter;
      filter.init(arena, config);
      arena.seal();
      const synthetic::RunErrors errors =
          synthetic::run(filter, synthetic::drive(options), options);
      mean.filter_rms_m += errors.filter_rms_m / kSeeds;
      mean.smoothed_rms_m += errors.smoothed_rms_m / kSeeds;
      mean.gps_rms_m += errors.gps_rms_m / kSeeds;
      mean.heading_rms_deg += errors.heading_rms_deg / kSeeds;
      mean.smoothed_heading_rms_deg += errors.smoothed_heading_rms_deg / kSeeds;
    }
  }
  state.counters["filter_rms_m"] = mean.filter_rms_m;
  state.counters["smoothed_rms_m"] = mean.smoothed_rms_m;
  state.counters["gps_rms_m"] = mean.gps_rms_m;
  state.counters["heading_rms_deg"] = mean.heading_rms_deg;
  state.counters["smoothed_heading_rms_deg"] = mean.smoothed_heading_rms_deg;
}
BENCHMARK(BM_AccuracyVsParticles)
    ->Arg(100)
    ->Arg(250)
    ->Arg(500)
    ->Arg(1000)
    ->Arg(2000)
    ->Arg(4000)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace
