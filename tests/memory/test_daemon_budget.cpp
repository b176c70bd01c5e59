// The on-robot daemon's pipeline thread allocates nothing once it runs: the
// simulated robot through the daemon's threads, laps of its loop, the pipeline thread's own
// allocations counted from its first message to its last (the device readers, the simulation
// and the output thread, which formats JSON, are other threads).
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <sstream>
#include <string>

#include "allocation_counter.hpp"
#include "daemon/daemon.hpp"

namespace blockmap::cli::daemon {
namespace {

namespace fs = std::filesystem;

struct PipelineAllocations {
  std::uint64_t calls = 0;
  std::uint64_t bytes = 0;
  std::string log;
  int status = -1;
};

PipelineAllocations run_laps(int laps, double duration_s) {
  const fs::path out =
      fs::temp_directory_path() / ("blockmap_daemon_budget_" + std::to_string(::getpid()));
  fs::remove_all(out);
  DaemonOptions options;
  options.config.whole_robot = hal::DeviceAddress{hal::DeviceBackend::kSim, "usc_block"};
  options.config_source = "test";
  options.mapping.out = out.string();
  options.laps = laps;
  options.sim.max_duration_s = duration_s;
  std::atomic<std::uint64_t> calls{0};
  std::atomic<std::uint64_t> bytes{0};
  testing::AllocationTally at_start;
  options.on_pipeline_thread = [&](bool started) {
    const testing::AllocationTally now = testing::allocations_on_this_thread();
    if (started) {
      at_start = now;
    } else {
      calls = now.calls - at_start.calls;
      bytes = now.bytes - at_start.bytes;
    }
  };
  PipelineAllocations result;
  Daemon daemon(options);
  std::ostringstream err;
  if (const std::string problem = daemon.start(err); !problem.empty()) {
    result.log = err.str() + problem;
    return result;
  }
  result.status = daemon.run(err);
  result.calls = calls;
  result.bytes = bytes;
  result.log = err.str();
  fs::remove_all(out);
  return result;
}

TEST(DaemonBudget, ThePipelineThreadAllocatesNothingLapAfterLap) {
  ASSERT_TRUE(testing::allocation_counting_active());
#if defined(BLOCKMAP_QUICK_WORLDS)
  const int laps = 1;
  const double duration_s = 40.0;
#else
  const int laps = 2;
  const double duration_s = 0.0;  // both laps: about six minutes of the robot's time
#endif
  const PipelineAllocations run = run_laps(laps, duration_s);
  ASSERT_EQ(run.status, 0) << run.log;
  EXPECT_NE(run.log.find("mapped "), std::string::npos) << run.log;
  EXPECT_EQ(run.calls, 0u) << run.bytes << " bytes allocated on the pipeline thread\n" << run.log;
}

}  // namespace
}  // namespace blockmap::cli::daemon
