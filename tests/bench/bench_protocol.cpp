// Decoder throughput in MB/s of device bytes, one core.
//   build/release/tests/bench/bench_protocol
#include <benchmark/benchmark.h>

#include <span>
#include <vector>

#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "test_data.hpp"

namespace blockmap {
namespace {

// Real receiver logs, concatenated until the stream is about 1 MiB.
std::vector<std::uint8_t> nmea_stream() {
  std::vector<std::uint8_t> stream;
  const char* logs[] = {"nmea/gpsd_furuno_gl_ga.log", "nmea/gpsd_nmea-fuzzy-cases.log",
                        "nmea/gpsd_bu353-glonass.log", "nmea/gpsd_beidou-gb.log"};
  while (stream.size() < (1U << 20)) {
    for (const char* log : logs) {
      const auto bytes = testing::read_bytes(testing::project_data(log));
      stream.insert(stream.end(), bytes.begin(), bytes.end());
    }
  }
  return stream;
}

void BM_NmeaDecode(benchmark::State& state) {
  const std::vector<std::uint8_t> stream = nmea_stream();
  hal::protocol::nmea::Decoder decoder;
  std::size_t sentences = 0;
  for (auto _ : state) {
    std::span<const std::uint8_t> rest(stream);
    while (!rest.empty()) {
      const auto step = decoder.push(rest, 0);
      rest = rest.subspan(step.consumed);
      sentences += step.sentence != nullptr ? 1U : 0U;
    }
  }
  benchmark::DoNotOptimize(sentences);
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(stream.size()));
  state.counters["sentences/s"] =
      benchmark::Counter(static_cast<double>(sentences), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_NmeaDecode);

// Status groups as a base sends them, counted as 8 payload bytes per frame.
void BM_SegwayRmpDecode(benchmark::State& state) {
  namespace rmp = hal::protocol::segway_rmp;
  rmp::StatusCycle cycle;
  cycle.odometry.fore_aft_distance_m = 12.0;
  const rmp::StatusFrames frames = rmp::encode_status(cycle, rmp::Config{});
  rmp::Decoder decoder;
  std::int64_t pushed = 0;
  for (auto _ : state) {
    for (const hal::CanFrame& frame : frames.frames) {
      benchmark::DoNotOptimize(decoder.push(frame, pushed));
      ++pushed;
    }
  }
  state.SetBytesProcessed(pushed * 8);
  state.SetItemsProcessed(pushed);
}
BENCHMARK(BM_SegwayRmpDecode);

}  // namespace
}  // namespace blockmap
