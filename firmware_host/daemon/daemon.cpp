#include "daemon/daemon.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <limits>
#include <optional>
#include <ostream>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/gps_observations.hpp"
#include "blockmap/hal/linux/serial_port.hpp"
#include "blockmap/hal/linux/socket_can_bus.hpp"
#include "blockmap/hal/linux/steady_clock.hpp"
#include "blockmap/hal/sim/robot.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "cli.hpp"
#include "daemon/device_link.hpp"
#include "daemon/snapshot.hpp"
#include "daemon/stop_signals.hpp"
#include "outputs/output_thread.hpp"

namespace blockmap::cli::daemon {
namespace {

constexpr TimestampNs kEndOfTime = std::numeric_limits<TimestampNs>::max();
constexpr double kMiB = 1024.0 * 1024.0;

std::string os_error(int error) {
  return std::generic_category().message(error);
}

TimestampNs ns_from_seconds(double seconds) {
  return static_cast<TimestampNs>(seconds * static_cast<double>(kNanosecondsPerSecond));
}

class SocketCanOpener final : public CanOpener {
 public:
  hal::CanBus& bus() override { return bus_; }
  std::string open(const hal::DeviceAddress& address) override { return bus_.open(address.name); }
  void close() override { bus_.close(); }

 private:
  hal::linux_backend::SocketCanBus bus_;
};

// A queue whose slots are taken at start-up.
template <typename T>
class OwnedQueue {
 public:
  explicit OwnedQueue(std::size_t capacity) : slots_(capacity + 1), queue_(slots_) {}
  SpscQueueRef<T>& queue() noexcept { return queue_; }
  [[nodiscard]] std::size_t bytes() const noexcept { return queue_.memory_bytes(); }

 private:
  std::vector<T> slots_;
  SpscQueueRef<T> queue_;
};

// What one device publishes and how healthy it is, as the pipeline thread reads it.
struct DeviceView {
  const char* name = "";
  const LinkHealth* link = nullptr;              // none for the simulated robot's devices
  std::function<std::uint64_t()> published;      // messages
  std::function<std::uint64_t()> rejected;       // queue full: the newest refused
  std::function<std::uint64_t()> dropped_bytes;  // what the decoder threw away (all reasons)
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

// ---------------------------------------------------------------------------------------------
// The robot's devices, each on its reader thread.
class RobotSource final : public Source {
 public:
  RobotSource(const hal::config::DaemonConfig& config, const hal::sim::RobotSpec& robot,
              std::unique_ptr<CanOpener> can, const hal::Clock& clock)
      : config_(config), can_(std::move(can)), clock_(clock) {
    timing_.silent_after_ns = ns_from_seconds(config.silent_after_s);
    timing_.reconnect_first_ns = ns_from_seconds(config.reconnect_first_s);
    timing_.reconnect_max_ns = ns_from_seconds(config.reconnect_max_s);
    odometry_.emplace(config.base_queue_messages);
    imu_.emplace(config.base_queue_messages);
    fixes_.emplace(config.fix_queue_messages);
    inlets.odometry = &odometry_->queue();
    inlets.imu = &imu_->queue();
    inlets.fixes = &fixes_->queue();
    if (config.base) {
      hal::devices::SegwayBaseConfig base_config;
      base_config.rmp.model = robot.base.model;
      base_config.rmp.yaw_sign = robot.base.yaw_sign;
      base_.emplace(can_->bus(), odometry_->queue(), imu_->queue(), base_config);
      add_link(
          "base",
          LinkDevice{[this] { return open_base(); }, [this] { can_->close(); },
                     [this](TimestampNs timeout) { return base_->poll(timeout); },
                     [this] { return base_->samples_published(); }},
          [this] { return base_->samples_rejected(); },
          [this] { return base_->decoder().drops().total(); });
    }
    for (std::size_t i = 0; i < config.lasers.size(); ++i) {
      if (!config.lasers[i]) {
        continue;
      }
      hal::devices::Lms2xxScannerConfig laser_config = hal::sim::lms2xx_config_for(robot.lasers[i]);
      laser_config.line_baud = config.lasers[i]->baud;
      laser_config.power_up_baud = config.lms_power_up_baud;
      auto laser =
          std::make_unique<Laser>(*config.lasers[i], config.scan_queue_messages, laser_config);
      Laser* l = laser.get();
      inlets.scans.resize(i + 1, nullptr);
      inlets.scans[i] = &l->scans.queue();
      l->name = "laser_" + robot.lasers[i].name;
      lasers_.push_back(std::move(laser));
      add_link(
          l->name,
          LinkDevice{[l] { return l->open(); }, [l] { l->port.close(); },
                     [l](TimestampNs timeout) { return l->device.poll(timeout); },
                     [l] { return l->device.scans_published(); }},
          [l] { return l->device.scans_rejected(); },
          [l] { return l->device.decoder().drops().total(); });
    }
    if (config.gps) {
      gps_.emplace(gps_port_, fixes_->queue(), hal::devices::GpsReceiverConfig{});
      add_link(
          "gps",
          LinkDevice{[this] { return gps_port_.open(config_.gps->name, config_.gps->baud); },
                     [this] { gps_port_.close(); },
                     [this](TimestampNs timeout) { return gps_->poll(timeout); },
                     [this] { return gps_->fixes_published(); }},
          [this] { return gps_->fixes_rejected(); },
          [this] { return gps_->decoder().drops().total(); });
    }
  }
  ~RobotSource() override { stop(); }

  std::string start(std::ostream& err) override {
    for (const auto& link : links_) {
      link->start();
      const LinkHealth& health = link->health();
      const LinkState state = health.state.load(std::memory_order_acquire);
      err << "device " << link->name() << ": " << to_string(state);
      if (state != LinkState::kUp) {
        err << " (" << link->last_problem() << "); retrying in the background";
      }
      err << '\n';
      seen_.push_back(state);
    }
    return {};
  }
  void stop() override {
    for (const auto& link : links_) {
      link->stop();
    }
  }
  [[nodiscard]] TimestampNs watermark_ns() const override {
    TimestampNs least = kEndOfTime;
    for (const auto& link : links_) {
      least = std::min(least, link->health().watermark_ns.load(std::memory_order_acquire));
    }
    return least;
  }
  [[nodiscard]] bool finished() const override { return false; }
  void report_changes(std::ostream& err) override {
    for (std::size_t i = 0; i < links_.size(); ++i) {
      const LinkHealth& health = links_[i]->health();
      const LinkState state = health.state.load(std::memory_order_acquire);
      if (state == seen_[i] || state == LinkState::kStopped) {
        continue;
      }
      err << "device " << links_[i]->name() << ": " << to_string(state);
      if (state == LinkState::kUp) {
        err << " (opened " << health.opens.load(std::memory_order_relaxed) << " times)";
      } else {
        err << " (" << links_[i]->last_problem() << "); reopening";
      }
      err << '\n';
      seen_[i] = state;
    }
  }
  [[nodiscard]] hal::FixTime fix_time() const override { return hal::FixTime::kReceiveClock; }
  [[nodiscard]] std::optional<hal::GeodeticPoint> origin() const override { return std::nullopt; }
  [[nodiscard]] std::size_t queue_bytes() const override {
    std::size_t bytes = odometry_->bytes() + imu_->bytes() + fixes_->bytes();
    for (const auto& laser : lasers_) {
      bytes += laser->scans.bytes();
    }
    return bytes;
  }

 private:
  struct Laser {
    Laser(hal::DeviceAddress address_in, std::size_t queue_messages,
          const hal::devices::Lms2xxScannerConfig& config)
        : address(std::move(address_in)),
          scans(queue_messages),
          device(port, scans.queue(), config) {}
    std::string open() {
      if (std::string problem = port.open(address.name, address.baud); !problem.empty()) {
        return problem;
      }
      // Continuous output again: a laser that was power-cycled has forgotten it (and its rate,
      // which the handshake brings back when configured).
      if (const IoStatus status = device.start(); status != IoStatus::kOk) {
        port.close();
        return address.name + ": the laser did not start (" +
               std::string(blockmap::to_string(status)) + ")";
      }
      return {};
    }
    hal::DeviceAddress address;
    std::string name;
    hal::linux_backend::SerialPort port;
    OwnedQueue<msg::LaserScan> scans;
    hal::devices::Lms2xxScanner device;
  };

  void add_link(const std::string& name, LinkDevice device, std::function<std::uint64_t()> rejected,
                std::function<std::uint64_t()> dropped_bytes) {
    DeviceView view;
    view.published = device.published;
    view.rejected = std::move(rejected);
    view.dropped_bytes = std::move(dropped_bytes);
    links_.push_back(std::make_unique<DeviceLink>(name, std::move(device), timing_, clock_));
    view.name = links_.back()->name().c_str();
    view.link = &links_.back()->health();
    devices.push_back(std::move(view));
  }
  std::string open_base() {
    if (std::string problem = can_->open(*config_.base); !problem.empty()) {
      return problem;
    }
    if (base_->install_filters() != IoStatus::kOk) {
      can_->close();
      return config_.base->name + ": the RMP's acceptance filters were refused";
    }
    return {};
  }

  hal::config::DaemonConfig config_;
  std::unique_ptr<CanOpener> can_;
  const hal::Clock& clock_;
  LinkTiming timing_;
  std::optional<OwnedQueue<msg::OdometrySample>> odometry_;
  std::optional<OwnedQueue<msg::ImuSample>> imu_;
  std::optional<OwnedQueue<msg::GpsFix>> fixes_;
  std::optional<hal::devices::SegwayBase> base_;
  std::vector<std::unique_ptr<Laser>> lasers_;
  hal::linux_backend::SerialPort gps_port_;
  std::optional<hal::devices::GpsReceiver> gps_;
  std::vector<std::unique_ptr<DeviceLink>> links_;
  std::vector<LinkState> seen_;
};

// ---------------------------------------------------------------------------------------------
// The simulated robot (`[devices] robot = "sim:WORLD"`): its simulation and devices on one
// thread, as fast as the pipeline takes their messages.
class SimSource final : public Source {
 public:
  SimSource(const hal::sim::World& world, const hal::sim::RobotSpec& robot,
            const hal::sim::SimOptions& options, std::string name)
      : robot_(std::make_unique<hal::sim::SimulatedRobot>(world, robot, options)),
        name_(std::move(name)) {
    inlets.odometry = &robot_->odometry();
    inlets.imu = &robot_->imu();
    inlets.fixes = &robot_->fixes();
    inlets.truth = &robot_->truth();
    hal::sim::SimulatedRobot* r = robot_.get();
    devices.push_back(DeviceView{"base", nullptr, [r] { return r->base().samples_published(); },
                                 [r] { return r->base().samples_rejected(); },
                                 [r] { return r->base().decoder().drops().total(); }});
    laser_names_.reserve(robot.lasers.size());
    for (std::size_t i = 0; i < r->laser_count(); ++i) {
      inlets.scans.push_back(&r->scans(i));
      laser_names_.push_back("laser_" + robot.lasers[i].name);
      devices.push_back(DeviceView{laser_names_.back().c_str(), nullptr,
                                   [r, i] { return r->laser(i).scans_published(); },
                                   [r, i] { return r->laser(i).scans_rejected(); },
                                   [r, i] { return r->laser(i).decoder().drops().total(); }});
    }
    devices.push_back(DeviceView{"gps", nullptr, [r] { return r->gps().fixes_published(); },
                                 [r] { return r->gps().fixes_rejected(); },
                                 [r] { return r->gps().decoder().drops().total(); }});
  }
  ~SimSource() override { stop(); }

  std::string start(std::ostream& err) override {
    if (robot_->start() != IoStatus::kOk) {
      return "the simulated lasers did not start";
    }
    err << "device " << name_ << ": the simulated robot, " << robot_->laser_count()
        << " lasers, faster than real time\n";
    watermark_ns_.store(robot_->simulation().now_ns(), std::memory_order_release);
    thread_ = std::thread([this] { run(); });
    return {};
  }
  void stop() override {
    stop_.store(true, std::memory_order_release);
    if (thread_.joinable()) {
      thread_.join();
    }
  }
  [[nodiscard]] TimestampNs watermark_ns() const override {
    return finished() ? kEndOfTime : watermark_ns_.load(std::memory_order_acquire);
  }
  [[nodiscard]] bool finished() const override { return finished_.load(std::memory_order_acquire); }
  void report_changes(std::ostream& /*err*/) override {}
  // The simulation's clock is UTC (the world's start_utc), as a recorded log's is.
  [[nodiscard]] hal::FixTime fix_time() const override { return hal::FixTime::kUtc; }
  [[nodiscard]] std::size_t queue_bytes() const override { return 0; }  // the robot's own
  [[nodiscard]] double elapsed_s() const { return robot_->simulation().elapsed_s(); }
  // The world's site, as `blockmap run` and `simulate` anchor it.
  [[nodiscard]] std::optional<hal::GeodeticPoint> origin() const override {
    return robot_->simulation().world().site.origin;
  }

 private:
  // Room in every queue for what one more step can publish: the simulation waits for the
  // pipeline rather than have its devices refuse messages.
  [[nodiscard]] bool room() const {
    const auto has_room = [](const auto& queue, std::size_t margin) {
      return queue.size_approx() + margin <= queue.capacity();
    };
    if (!has_room(*inlets.odometry, 16) || !has_room(*inlets.imu, 16) ||
        !has_room(*inlets.fixes, 4) || !has_room(*inlets.truth, 16)) {
      return false;
    }
    return std::all_of(inlets.scans.begin(), inlets.scans.end(),
                       [&](const auto* scans) { return has_room(*scans, 2); });
  }
  void run() {
    bool more = true;
    while (more && !stop_.load(std::memory_order_acquire)) {
      if (!room()) {
        std::this_thread::yield();
        continue;
      }
      more = robot_->advance();
      watermark_ns_.store(robot_->simulation().now_ns(), std::memory_order_release);
    }
    finished_.store(true, std::memory_order_release);
  }

  std::unique_ptr<hal::sim::SimulatedRobot> robot_;
  std::string name_;
  std::vector<std::string> laser_names_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<TimestampNs> watermark_ns_{0};
};

// ---------------------------------------------------------------------------------------------
// The pipeline thread: the oldest message no link can still undercut goes to the mapper, and
// what the mapper produced goes to the outputs; every health_every_s of data, a health record.
class Pipeline {
 public:
  // `origin`: the local frame's, when known (a resumed map's, a simulated world's).
  Pipeline(Source& source, MappingSession& session, const hal::config::DaemonConfig& config,
           const std::optional<hal::GeodeticPoint>& origin)
      : source_(source),
        session_(session),
        fixes_(origin ? hal::FixConverter(*origin, source.fix_time())
                      : hal::FixConverter(source.fix_time())),
        scans_(source.inlets.scans.size()),
        have_scan_(source.inlets.scans.size(), false),
        health_every_ns_(ns_from_seconds(config.health_every_s)),
        snapshot_every_ns_(ns_from_seconds(config.snapshot_every_s)) {}

  // Owns health.jsonl from here (nullptr: none).
  void set_health_file(std::FILE* file) noexcept { health_ = file; }
  void set_snapshots(SnapshotWriter* snapshots) noexcept { snapshots_ = snapshots; }
  void set_output_thread(OutputThread* output) noexcept { output_ = output; }

  // A snapshot of the map now, written at once (once the pipeline thread has ended); the last
  // one stays when this one cannot be written.
  void write_snapshot(std::ostream& err) {
    if (snapshots_ == nullptr) {
      return;
    }
    const std::size_t count = session_.mapper().save_planes(snapshots_->planes());
    if (const std::string problem = snapshots_->write(snapshot_header(), count); !problem.empty()) {
      err << "daemon: snapshot: " << problem << '\n';
    }
  }

  // The thread's body: runs until `drain` is set and everything published is mapped, or the
  // source has finished and everything is mapped.
  void run(const std::atomic<bool>& drain) {
    for (;;) {
      // The watermark is read before the queues: whatever it promises is in them by then.
      const bool draining = drain.load(std::memory_order_acquire);
      const bool finished = source_.finished();
      const TimestampNs watermark_ns = draining || finished ? kEndOfTime : source_.watermark_ns();
      const std::size_t fed = feed_up_to(watermark_ns);
      session_.pump();
      write_health_when_due();
      write_snapshot_when_due();
      if ((draining || finished) && fed == 0 && !refill()) {
        break;
      }
      if (fed == 0) {
        std::this_thread::sleep_for(std::chrono::microseconds(500));
      }
    }
    write_health(last_stamp_ns_);
  }

  [[nodiscard]] const hal::FixConverter& fixes() const noexcept { return fixes_; }
  [[nodiscard]] TimestampNs first_stamp_ns() const noexcept { return first_stamp_ns_; }
  [[nodiscard]] TimestampNs last_stamp_ns() const noexcept { return last_stamp_ns_; }

 private:
  // Takes the next message of every inlet whose head is free; whether any head is held.
  bool refill() {
    const Inlets& in = source_.inlets;
    if (!have_base_ && in.imu->size_approx() > 0) {
      // The base publishes odometry, then IMU: with an IMU sample there, its odometry is too.
      have_base_ = in.odometry->try_pop(odometry_) && in.imu->try_pop(imu_);
    }
    while (!have_fix_ && in.fixes->try_pop(fix_)) {
      have_fix_ = fixes_.convert(fix_, last_base_ns_, observation_, up_m_);
    }
    for (std::size_t i = 0; i < scans_.size(); ++i) {
      if (!have_scan_[i] && in.scans[i] != nullptr) {
        have_scan_[i] = in.scans[i]->try_pop(scans_[i]);
      }
    }
    if (in.truth != nullptr) {
      hal::sim::SimulatedRobot::TrueState unused;
      while (in.truth->try_pop(unused)) {
      }
    }
    return have_base_ || have_fix_ ||
           std::any_of(have_scan_.begin(), have_scan_.end(), [](bool held) { return held; });
  }

  // Feeds the held messages stamped up to `watermark_ns`, oldest first; how many.
  std::size_t feed_up_to(TimestampNs watermark_ns) {
    std::size_t fed = 0;
    pipeline::Mapper& mapper = session_.mapper();
    while (refill()) {
      TimestampNs oldest_ns = kEndOfTime;
      int which = -3;  // -1 base, -2 fix, i >= 0 laser i
      if (have_base_) {
        oldest_ns = odometry_.header.stamp_ns;
        which = -1;
      }
      if (have_fix_ && observation_.stamp_ns < oldest_ns) {
        oldest_ns = observation_.stamp_ns;
        which = -2;
      }
      for (std::size_t i = 0; i < scans_.size(); ++i) {
        if (have_scan_[i] && scans_[i].header.stamp_ns < oldest_ns) {
          oldest_ns = scans_[i].header.stamp_ns;
          which = static_cast<int>(i);
        }
      }
      if (oldest_ns > watermark_ns) {
        break;
      }
      if (which == -1) {
        last_base_ns_ = odometry_.header.stamp_ns;
        mapper.on_base(odometry_, imu_);
        have_base_ = false;
      } else if (which == -2) {
        mapper.on_fix(observation_, up_m_);
        have_fix_ = false;
      } else {
        const auto laser = static_cast<std::size_t>(which);
        static_cast<void>(mapper.on_scan(laser, scans_[laser]));
        have_scan_[laser] = false;
      }
      first_stamp_ns_ = std::min(first_stamp_ns_, oldest_ns);
      last_stamp_ns_ = std::max(last_stamp_ns_, oldest_ns);
      ++fed;
    }
    return fed;
  }

  void write_snapshot_when_due() {
    if (snapshots_ == nullptr || output_ == nullptr || snapshot_every_ns_ == 0 ||
        first_stamp_ns_ == kEndOfTime) {
      return;
    }
    if (next_snapshot_ns_ == 0) {
      next_snapshot_ns_ = first_stamp_ns_ + snapshot_every_ns_;
    }
    if (last_stamp_ns_ < next_snapshot_ns_) {
      return;
    }
    next_snapshot_ns_ = last_stamp_ns_ + snapshot_every_ns_;
    // The planes are encoded here; the output thread puts them on disk.
    if (output_->snapshot_pending()) {
      ++snapshots_skipped_;  // the last one is still being written: the next will carry this
      return;
    }
    const std::size_t count = session_.mapper().save_planes(snapshots_->planes());
    output_->put_snapshot(snapshots_->encode(snapshot_header(), count));
  }

  [[nodiscard]] SnapshotHeader snapshot_header() const {
    SnapshotHeader header;
    header.stamp_ns = last_stamp_ns_;
    header.next_id = session_.mapper().registry().next_id();
    if (fixes_.frame()) {
      header.origin = fixes_.frame()->origin();
    }
    return header;
  }

  void write_health_when_due() {
    if (last_stamp_ns_ == 0 || first_stamp_ns_ == kEndOfTime) {
      return;
    }
    if (next_health_ns_ == 0) {
      next_health_ns_ = first_stamp_ns_ + health_every_ns_;
    }
    if (last_stamp_ns_ >= next_health_ns_) {
      write_health(last_stamp_ns_);
      next_health_ns_ +=
          health_every_ns_ * (1 + (last_stamp_ns_ - next_health_ns_) / health_every_ns_);
    }
  }

  // One line of health.jsonl: each device's link and counters, the mapper's.
  void write_health(TimestampNs stamp_ns) {
    if (health_ == nullptr) {
      return;
    }
    const double t_s = first_stamp_ns_ == kEndOfTime || stamp_ns < first_stamp_ns_
                           ? 0.0
                           : seconds_from_ns(stamp_ns - first_stamp_ns_);
    std::fprintf(health_, R"({"t_s":%.3f,"devices":[)", t_s);
    bool first = true;
    for (const DeviceView& device : source_.devices) {
      const LinkState state = device.link != nullptr
                                  ? device.link->state.load(std::memory_order_acquire)
                                  : LinkState::kUp;
      std::fprintf(health_,
                   "%s{\"name\":\"%s\",\"state\":\"%s\",\"messages\":%llu,\"rejected\":%llu,"
                   "\"dropped\":%llu",
                   first ? "" : ",", device.name, to_string(state),
                   static_cast<unsigned long long>(device.published()),
                   static_cast<unsigned long long>(device.rejected()),
                   static_cast<unsigned long long>(device.dropped_bytes()));
      if (device.link != nullptr) {
        std::fprintf(health_, R"(,"opens":%llu,"open_failures":%llu,"losses":%llu,"silences":%llu)",
                     static_cast<unsigned long long>(device.link->opens.load()),
                     static_cast<unsigned long long>(device.link->open_failures.load()),
                     static_cast<unsigned long long>(device.link->losses.load()),
                     static_cast<unsigned long long>(device.link->silences.load()));
      }
      std::fputc('}', health_);
      first = false;
    }
    const pipeline::MapperCounters& c = session_.mapper().counters();
    std::fprintf(
        health_,
        "],\"mapper\":{\"base_samples\":%llu,\"fixes\":%llu,\"fixes_rejected\":%llu,"
        "\"scans\":%llu,\"scans_projected\":%llu,\"points\":%llu,\"extractions\":%llu,"
        "\"final_planes\":%zu,\"late\":%llu,\"scans_refused\":%llu},"
        "\"snapshots\":%llu,\"snapshot_failures\":%llu,\"snapshots_skipped\":%llu,"
        "\"output_waits\":%llu}\n",
        static_cast<unsigned long long>(c.base_samples), static_cast<unsigned long long>(c.fixes),
        static_cast<unsigned long long>(c.fixes_rejected), static_cast<unsigned long long>(c.scans),
        static_cast<unsigned long long>(c.scans_projected),
        static_cast<unsigned long long>(c.points), static_cast<unsigned long long>(c.extractions),
        session_.mapper().final_planes().size(), static_cast<unsigned long long>(c.messages_late),
        static_cast<unsigned long long>(c.scans_refused_full),
        static_cast<unsigned long long>(snapshots_ != nullptr ? snapshots_->written() : 0),
        static_cast<unsigned long long>(output_ != nullptr ? output_->snapshot_failures() : 0),
        static_cast<unsigned long long>(snapshots_skipped_),
        static_cast<unsigned long long>(output_ != nullptr ? output_->waits() : 0));
    std::fflush(health_);
  }

  Source& source_;
  MappingSession& session_;
  hal::FixConverter fixes_;
  msg::OdometrySample odometry_;
  msg::ImuSample imu_;
  bool have_base_ = false;
  msg::GpsFix fix_;
  localize::GpsObservation observation_;
  double up_m_ = 0.0;
  bool have_fix_ = false;
  std::vector<msg::LaserScan> scans_;
  std::vector<bool> have_scan_;
  TimestampNs last_base_ns_ = 0;
  TimestampNs first_stamp_ns_ = kEndOfTime;
  TimestampNs last_stamp_ns_ = 0;
  TimestampNs health_every_ns_;
  TimestampNs next_health_ns_ = 0;
  TimestampNs snapshot_every_ns_;
  TimestampNs next_snapshot_ns_ = 0;
  std::FILE* health_ = nullptr;
  SnapshotWriter* snapshots_ = nullptr;
  OutputThread* output_ = nullptr;
  std::uint64_t snapshots_skipped_ = 0;
};

}  // namespace

std::unique_ptr<CanOpener> socket_can_opener() {
  return std::make_unique<SocketCanOpener>();
}

class Daemon::Impl {
 public:
  Impl(DaemonOptions options, std::unique_ptr<CanOpener> can)
      : options_(std::move(options)), can_(std::move(can)) {}
  ~Impl() {
    if (health_ != nullptr) {
      std::fclose(health_);
    }
  }

  std::string start(std::ostream& err) {
    const hal::config::DaemonConfig& config = options_.config;
    hal::sim::RobotSpec robot = hal::sim::load_robot(config.robot);
    if (config.whole_robot && config.whole_robot->backend == hal::DeviceBackend::kReplay) {
      return "devices.robot: a folder of logs is mapped by `blockmap replay " +
             config.whole_robot->name + "`";
    }
    if (config.status_led || config.enable_switch) {
      return "devices.status_led/enable_switch: this build has no GPIO backend yet (libgpiod)";
    }
    if (!config.whole_robot) {
      hal::config::check_laser_count(config, robot.lasers.size(), options_.config_source);
      // Lasers without a device are left out of the mapper (their mounts with them).
      std::vector<hal::sim::LaserSpec> attached;
      std::vector<std::optional<hal::DeviceAddress>> addresses;
      for (std::size_t i = 0; i < config.lasers.size(); ++i) {
        if (config.lasers[i]) {
          attached.push_back(robot.lasers[i]);
          addresses.push_back(config.lasers[i]);
        }
      }
      robot.lasers = attached;
      options_.config.lasers = addresses;
    }
    pipeline::MapperConfig mapper_config = mapper_config_for(robot, options_.mapping);
    mapper_config.pose_source = pipeline::PoseSource::kLocalizer;
    if (config.whole_robot) {
      hal::sim::World world = hal::sim::load_world(config.whole_robot->name);
      if (std::string problem = hal::sim::repeat_laps(world, options_.laps); !problem.empty()) {
        return problem;
      }
      source_ = std::make_unique<SimSource>(world, robot, options_.sim,
                                            hal::to_string(*config.whole_robot));
    } else {
      source_ = std::make_unique<RobotSource>(options_.config, robot, std::move(can_), clock_);
    }
    // A map left by a run that ended (or crashed) in the same folder is carried on: its planes
    // come back, its frame is kept, and the streams are appended to.
    std::optional<Snapshot> resumed;
    if (!options_.mapping.out.empty()) {
      std::string problem;
      resumed = read_snapshot(options_.mapping.out, problem);
      if (!problem.empty()) {
        return problem;
      }
      options_.mapping.resume = resumed.has_value();
    }
    if (std::string problem = session_.start(mapper_config, options_.mapping, err, err);
        !problem.empty()) {
      return problem;
    }
    std::optional<hal::GeodeticPoint> origin = source_->origin();
    if (resumed) {
      session_.mapper().restore_planes(resumed->planes);
      if (resumed->header.origin) {
        origin = resumed->header.origin;
      }
      err << "resumed the map in " << options_.mapping.out << ": " << resumed->planes.size()
          << " planes, new ids from " << session_.mapper().registry().next_id() << '\n';
    }
    if (!options_.mapping.out.empty()) {
      snapshots_.emplace(options_.mapping.out, mapper_config.registry.max_live_planes +
                                                   mapper_config.registry.max_final_planes);
    }
    // The outputs' thread: room for the largest update the registry can make, the most
    // buildings, and a smoothing window's poses.
    OutputCapacity capacity;
    capacity.changes = session_.mapper().registry().change_capacity();
    capacity.buildings = mapper_config.buildings.max_buildings;
    capacity.poses = mapper_config.localizer.filter.history_steps + 1;
    output_thread_.emplace(session_.outputs(), capacity);
    char line[200];
    std::snprintf(line, sizeof line,
                  "daemon: device queues %.2f MiB, output queues %.2f MiB, snapshot buffers "
                  "%.2f MiB, taken at start-up\n",
                  static_cast<double>(source_->queue_bytes()) / kMiB,
                  static_cast<double>(output_thread_->memory_bytes()) / kMiB,
                  static_cast<double>(snapshots_ ? snapshots_->buffer_bytes() : 0) / kMiB);
    err << line;
    if (config.lock_memory && mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
      err << "daemon: lock_memory: not permitted (" << os_error(errno)
          << "; needs CAP_IPC_LOCK or a memlock limit): pages may be swapped out\n";
    }
    pipeline_.emplace(*source_, session_, options_.config, origin);
    if (snapshots_) {
      pipeline_->set_snapshots(&*snapshots_);
    }
    pipeline_->set_output_thread(&*output_thread_);
    if (snapshots_) {
      output_thread_->set_snapshots(&*snapshots_);
    }
    if (!options_.mapping.out.empty()) {
      const std::filesystem::path path =
          std::filesystem::path(options_.mapping.out) / "health.jsonl";
      health_ = std::fopen(path.c_str(), resumed ? "a" : "w");
      if (health_ == nullptr) {
        return path.string() + ": cannot write (" + os_error(errno) + ")";
      }
      // A buffer of its own, taken now, so that writing a record never allocates.
      std::setvbuf(health_, health_buffer_.data(), _IOFBF, health_buffer_.size());
      pipeline_->set_health_file(health_);
    }
    return source_->start(err);
  }

  int run(const std::atomic<bool>& stop_requested, std::ostream& err) {
    std::atomic<bool> drain{false};
    std::atomic<bool> done{false};
    session_.write_through(&*output_thread_);
    output_thread_->start();
    std::thread pipeline_thread([&] {
      if (options_.on_pipeline_thread) {
        options_.on_pipeline_thread(true);
      }
      pipeline_->run(drain);
      if (options_.on_pipeline_thread) {
        options_.on_pipeline_thread(false);
      }
      done.store(true, std::memory_order_release);
    });
    apply_realtime_priority(pipeline_thread, err);
    while (!stop_requested.load(std::memory_order_acquire) &&
           !done.load(std::memory_order_acquire)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      source_->report_changes(err);
    }
    if (stop_requested.load(std::memory_order_acquire)) {
      err << "daemon: stopping: the devices are closed, what they sent is mapped and written\n";
    }
    // The readers stop first, so that the drain sees everything they published.
    source_->stop();
    drain.store(true, std::memory_order_release);
    pipeline_thread.join();
    // What the output thread holds is written (a snapshot in hand among it); then the last
    // snapshot, and the end of the run, directly.
    output_thread_->finish();
    session_.write_through(nullptr);
    pipeline_->write_snapshot(err);
    std::optional<hal::GeodeticPoint> origin;
    if (pipeline_->fixes().frame()) {
      origin = pipeline_->fixes().frame()->origin();
    }
    if (const std::string problem = session_.finish(origin); !problem.empty()) {
      err << "blockmap: run: " << problem << '\n';
      return kExitFailure;
    }
    const TimestampNs first_ns = pipeline_->first_stamp_ns();
    const TimestampNs last_ns = pipeline_->last_stamp_ns();
    session_.report(err, last_ns > first_ns && first_ns != kEndOfTime
                             ? seconds_from_ns(last_ns - first_ns)
                             : 0.0);
    report_devices(err);
    return kExitOk;
  }

 private:
  void apply_realtime_priority(std::thread& thread, std::ostream& err) const {
    const int priority = options_.config.realtime_priority;
    if (priority <= 0) {
      return;
    }
    sched_param param{};
    param.sched_priority = priority;
    if (const int error = pthread_setschedparam(thread.native_handle(), SCHED_FIFO, &param);
        error != 0) {
      err << "daemon: realtime_priority " << priority << ": not permitted (" << os_error(error)
          << "; needs CAP_SYS_NICE or an rtprio limit): the pipeline runs at normal priority\n";
    } else {
      err << "daemon: the pipeline thread runs SCHED_FIFO at priority " << priority << '\n';
    }
  }

  void report_devices(std::ostream& err) const {
    for (const DeviceView& device : source_->devices) {
      err << "device " << device.name << ": " << device.published() << " messages, "
          << device.rejected() << " refused (queue full), " << device.dropped_bytes()
          << " dropped by the decoder";
      if (device.link != nullptr) {
        err << ", opened " << device.link->opens.load() << " times, lost "
            << device.link->losses.load() << ", silent " << device.link->silences.load();
      }
      err << '\n';
    }
  }

  DaemonOptions options_;
  std::unique_ptr<CanOpener> can_;
  hal::linux_backend::SteadyClock clock_;
  MappingSession session_;
  std::unique_ptr<Source> source_;
  std::optional<SnapshotWriter> snapshots_;
  std::optional<OutputThread> output_thread_;
  std::optional<Pipeline> pipeline_;
  std::FILE* health_ = nullptr;
  std::array<char, 1 << 16> health_buffer_{};
};

Daemon::Daemon(DaemonOptions options, std::unique_ptr<CanOpener> can)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(can))) {}

Daemon::~Daemon() = default;

std::string Daemon::start(std::ostream& err) {
  return impl_->start(err);
}

int Daemon::run(std::ostream& err) {
  return impl_->run(stop_requested_, err);
}

namespace {

std::atomic<Daemon*> signalled_daemon{nullptr};

extern "C" void on_stop_signal(int /*signal*/) {
  if (Daemon* daemon = signalled_daemon.load(std::memory_order_acquire); daemon != nullptr) {
    daemon->request_stop();
  }
}

}  // namespace

int run_daemon(DaemonOptions options, std::ostream& err) {
  Daemon daemon(std::move(options));
  if (const std::string problem = daemon.start(err); !problem.empty()) {
    err << "blockmap: run: " << problem << '\n';
    return kExitUsage;
  }
  signalled_daemon.store(&daemon, std::memory_order_release);
  int status = kExitFailure;
  {
    const StopSignals stop_signals(on_stop_signal);
    status = daemon.run(err);
  }
  signalled_daemon.store(nullptr, std::memory_order_release);
  return status;
}

}  // namespace blockmap::cli::daemon
