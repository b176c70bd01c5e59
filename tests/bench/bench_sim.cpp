// The simulator's speed: whole runs of the built-in worlds with the paper's robot (two LMS291 at
// 75 Hz, the RMP at 100 Hz, GPS at 4 Hz), on one core, as a multiple of real time.
//   build/release/tests/bench/bench_sim
// `realtime_x` is simulated seconds per wall-clock second. "devices" counts only the simulation
// (its bytes go nowhere); "logs" also writes every log file as `blockmap simulate` does.
#include <benchmark/benchmark.h>

#include <chrono>
#include <filesystem>
#include <string>

#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/run_recorder.hpp"
#include "blockmap/hal/sim/simulation.hpp"
#include "blockmap/hal/sim/world.hpp"

namespace blockmap::hal::sim {
namespace {

class NullSink final : public SimSink {
 public:
  void on_serial(std::size_t /*device*/, TimestampNs /*stamp_ns*/,
                 protocol::byte_log::Direction /*direction*/,
                 std::span<const std::uint8_t> bytes) override {
    bytes_ += bytes.size();
  }
  std::uint64_t bytes_ = 0;
};

void report(benchmark::State& state, double simulated_s, double wall_s, std::uint64_t scans,
            double distance_m) {
  state.counters["sim_s"] = simulated_s;
  state.counters["realtime_x"] = simulated_s / wall_s;
  state.counters["scans"] = static_cast<double>(scans);
  state.counters["metres"] = distance_m;
}

void BM_SimulateWorld(benchmark::State& state, const char* world_name, bool write_logs) {
  const World world = load_world(world_name);
  const config::RobotSpec robot = config::load_robot("paper_rmp");
  const std::filesystem::path folder =
      std::filesystem::temp_directory_path() / (std::string("blockmap_bench_") + world_name);
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    Simulation simulation(world, robot, SimOptions{});
    if (write_logs) {
      RunRecorder recorder(folder, simulation);
      simulation.run(recorder);
      recorder.finish(1);
    } else {
      NullSink sink;
      simulation.run(sink);
      benchmark::DoNotOptimize(sink.bytes_);
    }
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const SimStats& stats = simulation.stats();
    report(state, simulation.elapsed_s(), wall_s, stats.scans_sent[0] + stats.scans_sent[1],
           simulation.motion().distance_m());
  }
  std::filesystem::remove_all(folder);
}

BENCHMARK_CAPTURE(BM_SimulateWorld, usc_block_devices, "usc_block", false)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_SimulateWorld, usc_block_logs, "usc_block", true)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_SimulateWorld, benning_devices, "benning", false)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_SimulateWorld, benning_logs, "benning", true)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

}  // namespace
}  // namespace blockmap::hal::sim
