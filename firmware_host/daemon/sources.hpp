// Where the daemon's messages come from (daemon.hpp): the robot's devices, each on its reader
// thread with its watchdog (device_link.hpp), or the simulated robot on a thread of its own.
// Either fills the same queues (Inlets) and says up to when it has published (its watermark),
// which is all the pipeline thread's merge needs.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/can_bus.hpp"
#include "blockmap/hal/clock.hpp"
#include "blockmap/hal/config/daemon_config.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/hal/gps_observations.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/simulation.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "daemon/device_link.hpp"

namespace blockmap::cli::daemon {

inline constexpr TimestampNs kEndOfTime = std::numeric_limits<TimestampNs>::max();

[[nodiscard]] inline TimestampNs ns_from_seconds(double seconds) {
  return static_cast<TimestampNs>(seconds * static_cast<double>(kNanosecondsPerSecond));
}

// Where a can: address is opened. The robot's is SocketCAN; tests give their own (the host's
// kernel has no CAN).
class CanOpener {
 public:
  CanOpener() = default;
  CanOpener(const CanOpener&) = delete;
  CanOpener& operator=(const CanOpener&) = delete;
  virtual ~CanOpener() = default;
  [[nodiscard]] virtual hal::CanBus& bus() = 0;
  // Empty when it worked, else one line why not.
  [[nodiscard]] virtual std::string open(const hal::DeviceAddress& address) = 0;
  virtual void close() = 0;
};

// SocketCAN.
[[nodiscard]] std::unique_ptr<CanOpener> socket_can_opener();

// What one device publishes and how healthy it is, as the pipeline thread reads it.
struct DeviceView {
  const char* name = "";
  const LinkHealth* link = nullptr;              // none for the simulated robot's devices
  std::function<std::uint64_t()> published;      // messages
  std::function<std::uint64_t()> rejected;       // queue full: the newest refused
  std::function<std::uint64_t()> dropped_bytes;  // what the decoder threw away (all reasons)
  // Messages the device could not have sent, left out (the base's status groups); may be empty.
  std::function<std::uint64_t()> implausible;
};

// The queues the pipeline drains, whoever fills them.
struct Inlets {
  SpscQueueRef<msg::OdometrySample>* odometry = nullptr;
  SpscQueueRef<msg::ImuSample>* imu = nullptr;
  SpscQueueRef<msg::GpsFix>* fixes = nullptr;
  std::vector<SpscQueueRef<msg::LaserScan>*> scans;  // by the mapper's laser index
  SpscQueueRef<hal::sim::SimulatedRobot::TrueState>* truth = nullptr;  // drained, unused
};

// Whatever fills the inlets: the robot's devices or the simulated robot.
class Source {
 public:
  Source() = default;
  Source(const Source&) = delete;
  Source& operator=(const Source&) = delete;
  virtual ~Source() = default;
  // Opens the devices and prints their states; empty when mapping can start.
  [[nodiscard]] virtual std::string start(std::ostream& err) = 0;
  virtual void stop() = 0;
  // Nothing older than this will be published any more (kEndOfTime once finished).
  [[nodiscard]] virtual TimestampNs watermark_ns() const = 0;
  [[nodiscard]] virtual bool finished() const = 0;
  // Main thread: prints the devices that came or went since the last call.
  virtual void report_changes(std::ostream& err) = 0;
  [[nodiscard]] virtual hal::FixTime fix_time() const = 0;
  // Where the local frame is anchored when the source knows (else at the first good fix).
  [[nodiscard]] virtual std::optional<hal::GeodeticPoint> origin() const = 0;
  [[nodiscard]] virtual std::size_t queue_bytes() const = 0;

  Inlets inlets;
  std::vector<DeviceView> devices;
};

// The robot's devices of `config` (lasers already matched to `robot`'s), each on a reader
// thread once started.
[[nodiscard]] std::unique_ptr<Source> robot_source(const hal::config::DaemonConfig& config,
                                                   const hal::config::RobotSpec& robot,
                                                   std::unique_ptr<CanOpener> can,
                                                   const hal::Clock& clock);
// The recorded logs in `dir` (`blockmap replay`'s folder) of `robot`, named `name` in messages
// ("replay:DIR"): its lasers are the logs' (the caller leaves out those not recorded).
[[nodiscard]] std::unique_ptr<Source> replay_source(const std::filesystem::path& dir,
                                                    const hal::config::RobotSpec& robot,
                                                    const hal::config::DaemonConfig& config,
                                                    std::string name);
// The simulated robot in `world`, named `name` in messages ("sim:usc_block").
[[nodiscard]] std::unique_ptr<Source> sim_source(const hal::sim::World& world,
                                                 const hal::config::RobotSpec& robot,
                                                 const hal::sim::SimOptions& options,
                                                 std::string name);

}  // namespace blockmap::cli::daemon
