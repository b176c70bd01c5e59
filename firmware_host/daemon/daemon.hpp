// The on-robot daemon: `blockmap run --config FILE` with a [devices] table.
//
//   reader threads (DeviceLink)          pipeline thread              main thread
//   CAN -> SegwayBase    -> queue  |
//   tty -> Lms2xxScanner -> queue  |-> merge by time -> Mapper        signals, devices
//   tty -> GpsReceiver   -> queue  |   -> outputs, health.jsonl      coming and going,
//   gpio -> enable switch (panel.hpp) -> paused?                      the status LED
//
// One reader thread per device does the blocking I/O and the decoding and keeps its device
// open (device_link.hpp); the pipeline thread owns every piece of algorithm state and the
// outputs; the main thread waits for SIGINT/SIGTERM or the end of a simulated robot's run and
// reports devices coming and going. The merge hands the mapper the oldest waiting message
// that no link can still undercut (each link's watermark: it will publish nothing older), so
// the mapper sees the devices' messages in time order however the threads are scheduled.
// With `[devices] robot = "sim:WORLD"` one thread runs the simulated robot faster than real
// time in place of the readers, through the same queues and merge.
#pragma once

#include <atomic>
#include <functional>
#include <iosfwd>
#include <memory>
#include <string>

#include "blockmap/hal/can_bus.hpp"
#include "blockmap/hal/config/daemon_config.hpp"
#include "blockmap/hal/sim/simulation.hpp"
#include "commands/mapping.hpp"
#include "daemon/panel.hpp"
#include "daemon/sources.hpp"

namespace blockmap::cli::daemon {

struct DaemonOptions {
  hal::config::DaemonConfig config;
  std::string config_source;  // the file, for messages
  MappingOptions mapping;     // out, config (the mapping tables), udp, budget
  hal::sim::SimOptions sim;   // sim: the seed, the duration, a GPS silence
  int laps = 1;               // sim: drive a loop path this many times (a long run)
  // Called on the pipeline thread when its loop starts and when it has ended (the memory
  // tests count that thread's allocations between the two).
  std::function<void(bool started)> on_pipeline_thread;
};

class Daemon {
 public:
  explicit Daemon(DaemonOptions options, std::unique_ptr<CanOpener> can = socket_can_opener(),
                  std::unique_ptr<GpioOpener> gpio = gpiod_opener());
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  // Checks everything, takes the memory, prints the budget and opens the devices, printing
  // each one's state; empty when mapping can start, else one line why not.
  [[nodiscard]] std::string start(std::ostream& err);
  // Maps until stop() (or a signal through request_stop()), or until a simulated robot's run
  // ends; then flushes, writes the final outputs and reports. The process's exit status.
  int run(std::ostream& err);
  // Async-signal-safe: asks run() to finish.
  void request_stop() noexcept { stop_requested_.store(true, std::memory_order_release); }

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<bool> stop_requested_{false};
};

// `blockmap run --config FILE` when FILE has a [devices] table: the daemon, stopped by
// SIGINT/SIGTERM. Returns the exit status.
int run_daemon(DaemonOptions options, std::ostream& err);

}  // namespace blockmap::cli::daemon
