#include "daemon/daemon.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <ostream>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/gps_observations.hpp"
#include "blockmap/hal/linux/steady_clock.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"
#include "blockmap/hal/sim/world.hpp"
#include "cli.hpp"
#include "daemon/device_link.hpp"
#include "daemon/snapshot.hpp"
#include "daemon/sources.hpp"
#include "daemon/stop_signals.hpp"
#include "outputs/output_thread.hpp"

namespace blockmap::cli::daemon {
namespace {

constexpr double kMiB = 1024.0 * 1024.0;

std::string os_error(int error) {
  return std::generic_category().message(error);
}

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
  void set_panel(Panel* panel) noexcept {
    panel_ = panel;
    pps_ = panel->pps_edges();
  }

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
      // A fix is stamped back from its receipt to its UTC (FixConverter): the others wait for
      // the fixes that may still land before them. Without it an emulated ARM's reader, held
      // up by a second, had 21 fixes dropped as late in a minute.
      const TimestampNs watermark_ns =
          draining || finished ? kEndOfTime : source_.watermark_ns() - fixes_.backdating_ns();
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
    if (pps_ != nullptr) {
      for (TimestampNs edge_ns = 0; pps_->try_pop(edge_ns);) {
        fixes_.on_pps(edge_ns);
      }
    }
    while (!have_fix_ && in.fixes->try_pop(fix_)) {
      // The UTC day is the one of the fix's receipt (the base samples before it may not have
      // been fed yet: the queues are read ahead).
      const TimestampNs near_ns = fix_.header.stamp_ns != 0 ? fix_.header.stamp_ns : last_base_ns_;
      have_fix_ = fixes_.convert(fix_, near_ns, observation_, up_m_);
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
        if (mapping_enabled()) {
          static_cast<void>(mapper.on_scan(laser, scans_[laser]));
        } else {
          ++scans_paused_;  // the switch is off: the pose goes on, the map waits
        }
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

  [[nodiscard]] bool mapping_enabled() const noexcept {
    return panel_ == nullptr || panel_->mapping_enabled().load(std::memory_order_acquire);
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
      if (device.implausible) {
        std::fprintf(health_, R"(,"implausible":%llu)",
                     static_cast<unsigned long long>(device.implausible()));
      }
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
        "\"output_waits\":%llu,",
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
    std::fprintf(health_,
                 "\"mapping_enabled\":%s,\"scans_paused\":%llu,\"switch_changes\":%llu,"
                 "\"switch_failures\":%llu,\"pps_edges\":%llu,\"pps_fixes\":%zu}\n",
                 mapping_enabled() ? "true" : "false",
                 static_cast<unsigned long long>(scans_paused_),
                 static_cast<unsigned long long>(panel_ != nullptr ? panel_->switch_changes() : 0),
                 static_cast<unsigned long long>(panel_ != nullptr ? panel_->switch_failures() : 0),
                 static_cast<unsigned long long>(panel_ != nullptr ? panel_->pps_edges_seen() : 0),
                 fixes_.pps_fixes());
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
  const Panel* panel_ = nullptr;
  SpscQueueRef<TimestampNs>* pps_ = nullptr;  // the GPS's PPS edges, when wired
  std::uint64_t snapshots_skipped_ = 0;
  std::uint64_t scans_paused_ = 0;
};

}  // namespace

namespace {

// The robot of a folder of logs (`replay:DIR`): its robot.toml, as `blockmap replay` reads it,
// else [robot] spec; the lasers without a log are left out, and said so.
std::string recorded_robot(const hal::config::DaemonConfig& config, hal::config::RobotSpec& robot,
                           std::ostream& err) {
  const std::filesystem::path dir(config.whole_robot->name);
  if (!std::filesystem::is_directory(dir)) {
    return "devices.robot: " + dir.string() + " is not a folder of device logs";
  }
  const std::filesystem::path spec = dir / "robot.toml";
  robot = hal::config::load_robot(std::filesystem::exists(spec) ? spec.string() : config.robot);
  hal::config::require_lms2xx_lasers(robot, "the replay of byte logs");
  std::erase_if(robot.lasers, [&](const hal::config::LaserSpec& laser) {
    const bool recorded = std::filesystem::exists(dir / ("laser_" + laser.name + ".bytelog"));
    if (!recorded) {
      err << "replay: no laser_" << laser.name << ".bytelog: mapping without that laser\n";
    }
    return !recorded;
  });
  return {};
}

// A TiM of the robot's spec is on USB, an LMS2xx on a serial line.
std::string check_laser_protocols(const hal::config::DaemonConfig& config,
                                  const hal::config::RobotSpec& robot) {
  for (std::size_t i = 0; i < config.lasers.size(); ++i) {
    if (!config.lasers[i]) {
      continue;
    }
    const bool tim = robot.lasers[i].protocol == hal::config::LaserProtocol::kTim;
    const bool usb = config.lasers[i]->backend == hal::DeviceBackend::kUsb;
    if (tim != usb) {
      return "devices.lasers[" + std::to_string(i) + "]: \"" + hal::to_string(*config.lasers[i]) +
             "\" for the robot's laser " + robot.lasers[i].name + ", " +
             (tim ? "a SICK TiM (on usb:VENDOR:PRODUCT)" : "an LMS2xx (on serial:PATH@BAUD)");
    }
  }
  return {};
}

}  // namespace

class Daemon::Impl {
 public:
  Impl(DaemonOptions options, std::unique_ptr<CanOpener> can, std::unique_ptr<GpioOpener> gpio)
      : options_(std::move(options)), can_(std::move(can)), panel_(std::move(gpio)) {}
  ~Impl() {
    if (health_ != nullptr) {
      std::fclose(health_);
    }
  }

  std::string start(std::ostream& err) {
    const hal::config::DaemonConfig& config = options_.config;
    const bool replaying =
        config.whole_robot && config.whole_robot->backend == hal::DeviceBackend::kReplay;
    hal::config::RobotSpec robot;
    if (replaying) {
      if (std::string problem = recorded_robot(config, robot, err); !problem.empty()) {
        return problem;
      }
    } else {
      robot = hal::config::load_robot(config.robot);
    }
    if (!config.whole_robot) {
      hal::config::check_laser_count(config, robot.lasers.size(), options_.config_source);
      if (std::string problem = check_laser_protocols(config, robot); !problem.empty()) {
        return problem;
      }
      // Lasers without a device are left out of the mapper (their mounts with them).
      std::vector<hal::config::LaserSpec> attached;
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
    if (replaying) {
      source_ = replay_source(config.whole_robot->name, robot, config,
                              hal::to_string(*config.whole_robot));
    } else if (config.whole_robot) {
      hal::sim::World world = hal::sim::load_world(config.whole_robot->name);
      if (std::string problem = hal::sim::repeat_laps(world, options_.laps); !problem.empty()) {
        return problem;
      }
      source_ = sim_source(world, robot, options_.sim, hal::to_string(*config.whole_robot));
    } else {
      source_ = robot_source(options_.config, robot, std::move(can_), clock_);
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
    if (std::string problem = session_.start(mapper_config, options_.mapping, err);
        !problem.empty()) {
      return problem;
    }
    if (std::string problem = session_.open_outputs(options_.mapping, err); !problem.empty()) {
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
    pipeline_->set_panel(&panel_);
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
    if (std::string problem = panel_.start(config, err); !problem.empty()) {
      return problem;
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
      panel_.report_changes(err);
      panel_.show(
          led_pattern(panel_.mapping_enabled().load(std::memory_order_acquire), every_device_up()),
          clock_.now_ns());
    }
    if (stop_requested.load(std::memory_order_acquire)) {
      err << "daemon: stopping: the devices are closed, what they sent is mapped and written\n";
    }
    // The readers stop first, so that the drain sees everything they published.
    source_->stop();
    panel_.stop();
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

  [[nodiscard]] bool every_device_up() const {
    return std::all_of(
        source_->devices.begin(), source_->devices.end(), [](const DeviceView& device) {
          return device.link == nullptr ||
                 device.link->state.load(std::memory_order_acquire) == LinkState::kUp;
        });
  }

  void report_devices(std::ostream& err) const {
    for (const DeviceView& device : source_->devices) {
      err << "device " << device.name << ": " << device.published() << " messages, "
          << device.rejected() << " refused (queue full), " << device.dropped_bytes()
          << " dropped by the decoder";
      if (device.implausible) {
        err << ", " << device.implausible() << " no device could send left out";
      }
      if (device.link != nullptr) {
        err << ", opened " << device.link->opens.load() << " times, lost "
            << device.link->losses.load() << ", silent " << device.link->silences.load();
      }
      err << '\n';
    }
    if (panel_.switch_changes() > 0 || panel_.switch_failures() > 0 || panel_.led_failures() > 0) {
      err << "panel: the enable switch changed " << panel_.switch_changes() << " times, "
          << panel_.switch_failures() << " failed reads; " << panel_.led_failures()
          << " failed LED writes\n";
    }
  }

  DaemonOptions options_;
  std::unique_ptr<CanOpener> can_;
  Panel panel_;
  hal::linux_backend::SteadyClock clock_;
  MappingSession session_;
  std::unique_ptr<Source> source_;
  std::optional<SnapshotWriter> snapshots_;
  std::optional<OutputThread> output_thread_;
  std::optional<Pipeline> pipeline_;
  std::FILE* health_ = nullptr;
  std::array<char, 1 << 16> health_buffer_{};
};

Daemon::Daemon(DaemonOptions options, std::unique_ptr<CanOpener> can,
               std::unique_ptr<GpioOpener> gpio)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(can), std::move(gpio))) {}

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
