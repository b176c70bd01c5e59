// Decoder throughput in MB/s of device bytes, one core.
//   build/release/tests/bench/bench_protocol
#include <benchmark/benchmark.h>

#include <span>
#include <vector>

#include "blockmap/hal/protocol/hokuyo_scip2.hpp"
#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/hal/protocol/sick_cola.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
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

// UTM-30LX-sized continuous scans (1081 three-character values), as a sensor streams them.
void BM_Scip2Decode(benchmark::State& state) {
  namespace scip2 = hal::protocol::hokuyo_scip2;
  const std::vector<std::uint32_t> values(1081, 12345);
  std::vector<char> reply(8192);
  const std::size_t length = scip2::encode_scan_reply(reply, "MD0000108001000", "99", 100, values);
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(reply.data()),
                                            length);
  scip2::Config config;
  config.sensor.max_range_mm = 30000;
  scip2::Decoder decoder(config);
  for (auto _ : state) {
    std::span<const std::uint8_t> rest = bytes;
    while (!rest.empty()) rest = rest.subspan(decoder.push(rest, 0).consumed);
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(length));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Scip2Decode);

// A stream of telegrams decoded until nothing is left, for the codecs that may hand out
// held bytes with consumed == 0 (CoLa).
template <typename Decoder>
std::size_t drain_cola(Decoder& decoder, std::span<const std::uint8_t> bytes) {
  std::size_t scans = 0;
  for (;;) {
    const auto step = decoder.push(bytes, 0);
    bytes = bytes.subspan(step.consumed);
    scans += step.scan != nullptr ? 1U : 0U;
    if (!step.has_event() && bytes.empty()) return scans;
  }
}

// 16 real TiM scans (811 beams, DIST1 + RSSI1), CoLa B as sent over TCP.
void BM_ColaBDecode(benchmark::State& state) {
  const auto stream =
      testing::read_bytes(testing::project_data("cola/sick_scan_xd_test_pcapng_all16_frames.bin"));
  hal::protocol::sick_cola::StaticDecoder<> decoder;
  std::size_t scans = 0;
  for (auto _ : state) scans += drain_cola(decoder, stream);
  benchmark::DoNotOptimize(scans);
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(stream.size()));
}
BENCHMARK(BM_ColaBDecode);

// The same scans re-encoded as CoLa A (ASCII hex tokens), as a TiM sends them over USB/serial.
void BM_ColaADecode(benchmark::State& state) {
  namespace cola = hal::protocol::sick_cola;
  const auto binary =
      testing::read_bytes(testing::project_data("cola/sick_scan_xd_test_pcapng_all16_frames.bin"));
  cola::StaticDecoder<> reader;
  std::vector<std::uint8_t> stream;
  std::vector<std::uint8_t> telegram(cola::kDefaultTelegramCapacityBytes);
  std::span<const std::uint8_t> rest(binary);
  for (;;) {
    const auto step = reader.push(rest, 0);
    rest = rest.subspan(step.consumed);
    if (step.scan != nullptr) {
      const std::size_t n = cola::encode_scan(cola::Dialect::kColaA, *step.scan,
                                              cola::ScanTelegramFields{}, telegram);
      stream.insert(stream.end(), telegram.begin(),
                    telegram.begin() + static_cast<std::ptrdiff_t>(n));
    }
    if (!step.has_event() && rest.empty()) break;
  }
  cola::StaticDecoder<> decoder;
  std::size_t scans = 0;
  for (auto _ : state) scans += drain_cola(decoder, stream);
  benchmark::DoNotOptimize(scans);
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(stream.size()));
}
BENCHMARK(BM_ColaADecode);

// LMS291 180 degree / 0.5 degree scans in mm (732-byte telegrams), as streamed at 500 kBd.
void BM_Lms2xxDecode(benchmark::State& state) {
  namespace lms = hal::protocol::sick_lms2xx;
  std::vector<std::uint16_t> values(361);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = static_cast<std::uint16_t>(1000 + i);
  std::vector<std::uint8_t> stream;
  std::vector<std::uint8_t> telegram(lms::kMaxTelegramBytes);
  for (int i = 0; i < 64; ++i) {
    const std::size_t n = lms::encode_measured_values(telegram, values, lms::Units::kMm, 0x10);
    stream.insert(stream.end(), telegram.begin(),
                  telegram.begin() + static_cast<std::ptrdiff_t>(n));
  }
  lms::Decoder decoder;
  std::size_t scans = 0;
  for (auto _ : state) {
    std::span<const std::uint8_t> rest(stream);
    for (;;) {
      const auto step = decoder.push(rest, 0);
      rest = rest.subspan(step.consumed);
      if (step.event == lms::Decoder::Event::kNone) break;
      scans += step.event == lms::Decoder::Event::kTelegram ? 1U : 0U;
    }
  }
  benchmark::DoNotOptimize(scans);
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(stream.size()));
}
BENCHMARK(BM_Lms2xxDecode);

}  // namespace
}  // namespace blockmap
