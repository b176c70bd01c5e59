// The simulator streams: after construction, a run of any length allocates nothing and its
// memory stays what it was, whether its output goes to a test, to the robot's ports or to log
// files.
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>

#include <unistd.h>

#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/sim/run_recorder.hpp"
#include "blockmap/hal/sim/sim_ports.hpp"
#include "blockmap/hal/sim/simulation.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "memory_assertions.hpp"

namespace blockmap::hal::sim {
namespace {

class CountingSink final : public SimSink {
 public:
  void on_can_frame(TimestampNs /*stamp_ns*/, const CanFrame& /*frame*/) override { ++frames; }
  void on_serial(std::size_t /*device*/, TimestampNs /*stamp_ns*/,
                 protocol::byte_log::Direction /*direction*/,
                 std::span<const std::uint8_t> bytes) override {
    serial_bytes += bytes.size();
  }
  void on_beam(std::size_t /*laser*/, const BeamTruth& beam) override {
    beams += beam.returned ? 1U : 0U;
  }
  std::uint64_t frames = 0;
  std::uint64_t serial_bytes = 0;
  std::uint64_t beams = 0;
};

void run_until(Simulation& simulation, SimSink& sink, double seconds) {
  while (simulation.elapsed_s() < seconds && simulation.step(sink)) {
  }
}

TEST(SimulatorBudget, ARunAllocatesNothingAfterConstruction) {
  SimOptions options;
  options.max_duration_s = 60.0;
  Simulation simulation(load_world("benning"), config::load_robot("paper_rmp"), options);
  CountingSink sink;
  run_until(simulation, sink, 1.0);  // the lasers' handshake, the first scans
  const std::size_t bytes = simulation.memory_bytes();
  EXPECT_NO_ALLOCATIONS(run_until(simulation, sink, 60.0));
  EXPECT_EQ(simulation.memory_bytes(), bytes);
  EXPECT_GT(sink.serial_bytes, 3'000'000u);
  EXPECT_GT(sink.beams, 600'000u);
  EXPECT_LT(bytes, 32u << 20) << "the simulator's whole state (mostly the ground's height grid)";
}

TEST(SimulatorBudget, WritingTheLogsAllocatesNothingEither) {
  SimOptions options;
  options.max_duration_s = 20.0;
  Simulation simulation(load_world("usc_block"), config::load_robot("paper_rmp"), options);
  const std::filesystem::path folder =
      std::filesystem::temp_directory_path() / ("blockmap_budget_" + std::to_string(::getpid()));
  {
    RunRecorder recorder(folder, simulation);
    run_until(simulation, recorder, 1.0);
    EXPECT_NO_ALLOCATIONS(run_until(simulation, recorder, 20.0));
    recorder.finish(options.seed);
  }
  std::filesystem::remove_all(folder);
}

TEST(SimulatorBudget, FeedingTheRobotsPortsAllocatesNothing) {
  SimOptions options;
  options.max_duration_s = 5.0;
  Simulation simulation(load_world("usc_block"), config::load_robot("paper_rmp"), options);
  ManualClock clock(simulation.start_ns());
  std::array<PendingCanFrame, 64> pending{};
  std::array<CanFrame, 4> sent{};
  LoopbackCanBus can(clock, {}, pending, sent);
  std::array<SimSerialPort, 3> serial;
  const std::array<SimSerialPort*, 3> ports = {&serial[0], &serial[1], &serial[2]};
  SimPorts sink(clock, can, ports);
  std::array<std::uint8_t, 1024> buffer{};
  CanFrame frame;
  const auto drain = [&] {
    while (can.receive(frame, 0).status == IoStatus::kOk) {
    }
    for (SimSerialPort& port : serial) {
      while (port.read(buffer, 0).status == IoStatus::kOk) {
      }
    }
  };
  while (simulation.elapsed_s() < 1.0 && simulation.step(sink)) {
    drain();
  }
  EXPECT_NO_ALLOCATIONS({
    while (simulation.step(sink)) {
      drain();
    }
  });
  EXPECT_EQ(sink.can_overflows(), 0u);
}

}  // namespace
}  // namespace blockmap::hal::sim
