#include "daemon/sources.hpp"

#include <algorithm>
#include <chrono>
#include <ostream>
#include <thread>
#include <utility>

#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/linux/libusb_bulk.hpp"
#include "blockmap/hal/linux/serial_port.hpp"
#include "blockmap/hal/linux/socket_can_bus.hpp"
#include "commands/recorded_run.hpp"

namespace blockmap::cli::daemon {
namespace {

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

// ---------------------------------------------------------------------------------------------
// The robot's devices, each on its reader thread.
class RobotSource final : public Source {
 public:
  RobotSource(const hal::config::DaemonConfig& config, const hal::config::RobotSpec& robot,
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
      base_.emplace(can_->bus(), odometry_->queue(), imu_->queue(),
                    hal::config::segway_base_config_for(robot));
      add_link(
          "base",
          LinkDevice{[this] { return open_base(); }, [this] { can_->close(); },
                     [this](TimestampNs timeout) { return base_->poll(timeout); },
                     [this] { return base_->samples_published(); }},
          [this] { return base_->samples_rejected(); },
          [this] { return base_->decoder().drops().total(); },
          [this] { return base_->groups_implausible(); });
    }
    for (std::size_t i = 0; i < config.lasers.size(); ++i) {
      if (!config.lasers[i]) {
        continue;
      }
      std::unique_ptr<Laser> laser;
      if (config.lasers[i]->backend == hal::DeviceBackend::kUsb) {
        laser = std::make_unique<UsbLaser>(*config.lasers[i], config.scan_queue_messages,
                                           hal::devices::TimScannerConfig{});
      } else {
        hal::devices::Lms2xxScannerConfig laser_config =
            hal::config::lms2xx_config_for(robot.lasers[i]);
        laser_config.line_baud = config.lasers[i]->baud;
        laser_config.power_up_baud = config.lms_power_up_baud;
        laser = std::make_unique<SerialLaser>(*config.lasers[i], config.scan_queue_messages,
                                              laser_config);
      }
      Laser* l = laser.get();
      inlets.scans.resize(i + 1, nullptr);
      inlets.scans[i] = &l->scans.queue();
      l->name = "laser_" + robot.lasers[i].name;
      lasers_.push_back(std::move(laser));
      add_link(
          l->name,
          LinkDevice{[l] { return l->open(); }, [l] { l->close(); },
                     [l](TimestampNs timeout) { return l->poll(timeout); },
                     [l] { return l->published(); }},
          [l] { return l->rejected(); }, [l] { return l->dropped_bytes(); });
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
  // A laser on its port: what its link opens, closes, polls and counts.
  struct Laser {
    Laser(hal::DeviceAddress address_in, std::size_t queue_messages)
        : address(std::move(address_in)), scans(queue_messages) {}
    Laser(const Laser&) = delete;
    Laser& operator=(const Laser&) = delete;
    virtual ~Laser() = default;
    virtual std::string open() = 0;
    virtual void close() = 0;
    virtual IoStatus poll(TimestampNs timeout_ns) = 0;
    [[nodiscard]] virtual std::uint64_t published() const = 0;
    [[nodiscard]] virtual std::uint64_t rejected() const = 0;
    [[nodiscard]] virtual std::uint64_t dropped_bytes() const = 0;
    // The start command again after every opening: a laser that was power-cycled (or
    // unplugged) has forgotten its continuous output.
    std::string started(IoStatus status) {
      if (status == IoStatus::kOk) {
        return {};
      }
      close();
      return hal::to_string(address) + ": the laser did not start (" +
             std::string(blockmap::to_string(status)) + ")";
    }
    hal::DeviceAddress address;
    std::string name;
    OwnedQueue<msg::LaserScan> scans;
  };

  // An LMS2xx on a serial line; a configured handshake brings back its rate too.
  struct SerialLaser final : Laser {
    SerialLaser(hal::DeviceAddress address_in, std::size_t queue_messages,
                const hal::devices::Lms2xxScannerConfig& config)
        : Laser(std::move(address_in), queue_messages), device(port, scans.queue(), config) {}
    std::string open() override {
      if (std::string problem = port.open(address.name, address.baud); !problem.empty()) {
        return problem;
      }
      return started(device.start());
    }
    void close() override { port.close(); }
    IoStatus poll(TimestampNs timeout_ns) override { return device.poll(timeout_ns); }
    [[nodiscard]] std::uint64_t published() const override { return device.scans_published(); }
    [[nodiscard]] std::uint64_t rejected() const override { return device.scans_rejected(); }
    [[nodiscard]] std::uint64_t dropped_bytes() const override {
      return device.decoder().drops().total();
    }
    hal::linux_backend::SerialPort port;
    hal::devices::Lms2xxScanner device;
  };

  // A TiM over USB: found again by its ids after an unplug.
  struct UsbLaser final : Laser {
    UsbLaser(hal::DeviceAddress address_in, std::size_t queue_messages,
             const hal::devices::TimScannerConfig& config)
        : Laser(std::move(address_in), queue_messages), device(usb, scans.queue(), config) {}
    std::string open() override {
      if (std::string problem = usb.open(address.vendor_id, address.product_id, address.name);
          !problem.empty()) {
        return problem;
      }
      return started(device.start());
    }
    void close() override { usb.close(); }
    IoStatus poll(TimestampNs timeout_ns) override { return device.poll(timeout_ns); }
    [[nodiscard]] std::uint64_t published() const override { return device.scans_published(); }
    [[nodiscard]] std::uint64_t rejected() const override { return device.scans_rejected(); }
    [[nodiscard]] std::uint64_t dropped_bytes() const override {
      return device.decoder().drops().total();
    }
    hal::linux_backend::LibusbBulk usb;
    hal::devices::TimScanner device;
  };

  void add_link(const std::string& name, LinkDevice device, std::function<std::uint64_t()> rejected,
                std::function<std::uint64_t()> dropped_bytes,
                std::function<std::uint64_t()> implausible = {}) {
    DeviceView view;
    view.published = device.published;
    view.rejected = std::move(rejected);
    view.dropped_bytes = std::move(dropped_bytes);
    view.implausible = std::move(implausible);
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
// A source whose messages one thread of its own publishes, faster than real time, on the run's
// UTC clock (the simulated robot, recorded logs): the thread, its stop request, its watermark.
class OwnThreadSource : public Source {
 public:
  ~OwnThreadSource() override { stop(); }
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
  // The simulation's clock and a recorded run's are UTC (the world's start_utc, the log's).
  [[nodiscard]] hal::FixTime fix_time() const override { return hal::FixTime::kUtc; }

 protected:
  // Runs `body` on the thread; it publishes, then calls finish().
  template <typename Body>
  void launch(Body body) {
    thread_ = std::thread(std::move(body));
  }
  [[nodiscard]] bool stopping() const noexcept { return stop_.load(std::memory_order_acquire); }
  void publish_watermark(TimestampNs stamp_ns) noexcept {
    watermark_ns_.store(stamp_ns, std::memory_order_release);
  }
  void finish() noexcept { finished_.store(true, std::memory_order_release); }

 private:
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<TimestampNs> watermark_ns_{0};
};

// ---------------------------------------------------------------------------------------------
// The simulated robot (`[devices] robot = "sim:WORLD"`): its simulation and devices on one
// thread, as fast as the pipeline takes their messages.
class SimSource final : public OwnThreadSource {
 public:
  SimSource(const hal::sim::World& world, const hal::config::RobotSpec& robot,
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
                                 [r] { return r->base().decoder().drops().total(); },
                                 [r] { return r->base().groups_implausible(); }});
    laser_names_.reserve(robot.lasers.size());
    for (std::size_t i = 0; i < r->laser_count(); ++i) {
      inlets.scans.push_back(&r->scans(i));
      laser_names_.push_back("laser_" + robot.lasers[i].name);
      devices.push_back(DeviceView{
          laser_names_.back().c_str(), nullptr, [r, i] { return r->laser(i).scans_published(); },
          [r, i] { return r->laser(i).scans_rejected(); },
          [r, i] { return r->laser(i).decoder().drops().total(); }, nullptr});
    }
    devices.push_back(DeviceView{"gps", nullptr, [r] { return r->gps().fixes_published(); },
                                 [r] { return r->gps().fixes_rejected(); },
                                 [r] { return r->gps().decoder().drops().total(); }, nullptr});
  }
  ~SimSource() override { stop(); }  // before the robot the thread runs goes

  std::string start(std::ostream& err) override {
    if (robot_->start() != IoStatus::kOk) {
      return "the simulated lasers did not start";
    }
    err << "device " << name_ << ": the simulated robot, " << robot_->laser_count()
        << " lasers, faster than real time\n";
    publish_watermark(robot_->simulation().now_ns());
    launch([this] { run(); });
    return {};
  }
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
    while (more && !stopping()) {
      if (!room()) {
        std::this_thread::yield();
        continue;
      }
      more = robot_->advance();
      publish_watermark(robot_->simulation().now_ns());
    }
    finish();
  }

  std::unique_ptr<hal::sim::SimulatedRobot> robot_;
  std::string name_;
  std::vector<std::string> laser_names_;
};

// ---------------------------------------------------------------------------------------------
// Recorded logs (`[devices] robot = "replay:DIR"`): the devices' logs read on one thread, each
// device's messages in its queue in the order they were recorded, as fast as the pipeline
// takes them (a full queue waits; nothing recorded is dropped).
class ReplaySource final : public OwnThreadSource {
 public:
  ReplaySource(const std::filesystem::path& dir, const hal::config::RobotSpec& robot,
               const hal::config::DaemonConfig& config, std::string name)
      : run_(dir, hal::config::segway_base_config_for(robot), robot.lasers),
        name_(std::move(name)),
        odometry_(config.base_queue_messages),
        imu_(config.base_queue_messages),
        fixes_(config.fix_queue_messages) {
    inlets.odometry = &odometry_.queue();
    inlets.imu = &imu_.queue();
    inlets.fixes = &fixes_.queue();
    scans_.reserve(robot.lasers.size());
    for (std::size_t i = 0; i < robot.lasers.size(); ++i) {
      scans_.push_back(std::make_unique<OwnedQueue<msg::LaserScan>>(config.scan_queue_messages));
      inlets.scans.push_back(&scans_.back()->queue());
    }
    published_.resize(robot.lasers.size() + 2);
    for (auto& count : published_) {
      count = std::make_unique<std::atomic<std::uint64_t>>(0);
    }
    const auto never = [] { return std::uint64_t{0}; };
    devices.push_back(DeviceView{"base", nullptr, [this] { return published_[0]->load(); }, never,
                                 [this] { return run_.base().decoder().drops().total(); },
                                 [this] { return run_.base().groups_implausible(); }});
    laser_names_.reserve(robot.lasers.size());
    for (std::size_t i = 0; i < robot.lasers.size(); ++i) {
      laser_names_.push_back("laser_" + robot.lasers[i].name);
      devices.push_back(DeviceView{
          laser_names_.back().c_str(), nullptr, [this, i] { return published_[i + 2]->load(); },
          never, [this, i] { return run_.laser(i).decoder().drops().total(); }, nullptr});
    }
    devices.push_back(DeviceView{"gps", nullptr, [this] { return published_[1]->load(); }, never,
                                 [this] { return run_.gps().decoder().drops().total(); }, nullptr});
  }
  ~ReplaySource() override { stop(); }  // before the logs the thread reads go

  std::string start(std::ostream& err) override {
    if (std::string problem = run_.open_error(); !problem.empty()) {
      return problem;
    }
    err << "device " << name_ << ": recorded logs, " << run_.laser_count()
        << " lasers, as fast as the pipeline takes them\n";
    launch([this] { run(); });
    return {};
  }
  [[nodiscard]] std::optional<hal::GeodeticPoint> origin() const override { return std::nullopt; }
  [[nodiscard]] std::size_t queue_bytes() const override {
    std::size_t bytes = odometry_.bytes() + imu_.bytes() + fixes_.bytes();
    for (const auto& scans : scans_) {
      bytes += scans->bytes();
    }
    return bytes;
  }

 private:
  // Waits for room in `queue` (or stop()); whether `value` went in.
  template <typename T>
  bool push(SpscQueueRef<T>& queue, const T& value) {
    while (!queue.try_push(value)) {
      if (stopping()) {
        return false;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    return true;
  }

  // The devices' next messages, oldest first, each into its queue; the watermark follows.
  void run() {
    msg::OdometrySample odometry;
    msg::ImuSample imu;
    msg::GpsFix fix;
    std::vector<msg::LaserScan> scans(run_.laser_count());
    bool have_base = run_.next_base(odometry, imu);
    TimestampNs last_ns = have_base ? odometry.header.stamp_ns : 0;
    // An NMEA log's bytes carry no receive times: a recorded run's clock is UTC, so a fix is
    // placed at its own UTC, on the day of the base samples around it (as `blockmap replay`
    // orders it).
    const auto next_fix = [&] {
      const bool more = run_.next_fix(fix);
      if (more) {
        fix.header.stamp_ns = fix.has_time ? hal::fix_stamp_ns(fix, last_ns) : last_ns;
      }
      return more;
    };
    bool have_fix = next_fix();
    std::vector<bool> have_scan(scans.size());
    for (std::size_t i = 0; i < scans.size(); ++i) {
      have_scan[i] = run_.next_scan(i, scans[i]);
    }
    while (!stopping()) {
      TimestampNs oldest_ns = kEndOfTime;
      int which = -3;  // -1 base, -2 fix, i >= 0 laser i
      if (have_base) {
        oldest_ns = odometry.header.stamp_ns;
        which = -1;
      }
      if (have_fix && fix.header.stamp_ns < oldest_ns) {
        oldest_ns = fix.header.stamp_ns;
        which = -2;
      }
      for (std::size_t i = 0; i < scans.size(); ++i) {
        if (have_scan[i] && scans[i].header.stamp_ns < oldest_ns) {
          oldest_ns = scans[i].header.stamp_ns;
          which = static_cast<int>(i);
        }
      }
      if (which == -3) {
        break;  // every log is done
      }
      bool pushed = false;
      if (which == -1) {
        pushed = push(*inlets.odometry, odometry) && push(*inlets.imu, imu);
        last_ns = odometry.header.stamp_ns;
        have_base = run_.next_base(odometry, imu);
        published_[0]->fetch_add(1, std::memory_order_relaxed);
      } else if (which == -2) {
        pushed = push(*inlets.fixes, fix);
        have_fix = next_fix();
        published_[1]->fetch_add(1, std::memory_order_relaxed);
      } else {
        const auto i = static_cast<std::size_t>(which);
        pushed = push(*inlets.scans[i], scans[i]);
        have_scan[i] = run_.next_scan(i, scans[i]);
        published_[i + 2]->fetch_add(1, std::memory_order_relaxed);
      }
      if (!pushed) {
        break;
      }
      publish_watermark(oldest_ns);
    }
    finish();
  }

  RecordedRun run_;
  std::string name_;
  OwnedQueue<msg::OdometrySample> odometry_;
  OwnedQueue<msg::ImuSample> imu_;
  OwnedQueue<msg::GpsFix> fixes_;
  std::vector<std::unique_ptr<OwnedQueue<msg::LaserScan>>> scans_;
  std::vector<std::unique_ptr<std::atomic<std::uint64_t>>> published_;  // base, gps, lasers
  std::vector<std::string> laser_names_;
};

}  // namespace

std::unique_ptr<Source> replay_source(const std::filesystem::path& dir,
                                      const hal::config::RobotSpec& robot,
                                      const hal::config::DaemonConfig& config, std::string name) {
  return std::make_unique<ReplaySource>(dir, robot, config, std::move(name));
}

std::unique_ptr<CanOpener> socket_can_opener() {
  return std::make_unique<SocketCanOpener>();
}

std::unique_ptr<Source> robot_source(const hal::config::DaemonConfig& config,
                                     const hal::config::RobotSpec& robot,
                                     std::unique_ptr<CanOpener> can, const hal::Clock& clock) {
  return std::make_unique<RobotSource>(config, robot, std::move(can), clock);
}

std::unique_ptr<Source> sim_source(const hal::sim::World& world,
                                   const hal::config::RobotSpec& robot,
                                   const hal::sim::SimOptions& options, std::string name) {
  return std::make_unique<SimSource>(world, robot, options, std::move(name));
}

}  // namespace blockmap::cli::daemon
