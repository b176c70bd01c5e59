#include "blockmap/hal/sim/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "blockmap/core/check.hpp"
#include "sim_devices.hpp"

namespace blockmap::hal::sim {

struct Simulation::Impl {
  Impl(World world_in, config::RobotSpec robot_in, const SimOptions& options_in)
      : world(std::move(world_in)),
        robot(std::move(robot_in)),
        options(options_in),
        scene(world, options.seed),
        motion(robot.base, world.path, scene.terrain()),
        rmp(robot.base, options.seed),
        gps(robot.gps, world.site, robot.lasers.size(), options.seed),
        context{scene, motion,
                static_cast<TimestampNs>(std::llround(world.site.start_unix_s * 1e9)),
                detail::kNever} {
    lasers.reserve(robot.lasers.size());
    for (std::size_t i = 0; i < robot.lasers.size(); ++i) {
      lasers.push_back(std::make_unique<detail::SimLms>(robot.lasers[i], i, options.seed));
    }
    stats.scans_sent.assign(robot.lasers.size(), 0);
    stats.scans_skipped.assign(robot.lasers.size(), 0);
    stats.beams_returned.assign(robot.lasers.size(), 0);
    now_ns = context.start_ns;
    if (options.gps_silent_to_s > options.gps_silent_from_s) {
      gps.set_silence(context.stamp(options.gps_silent_from_s),
                      context.stamp(options.gps_silent_to_s));
    }
    gps.set_jumps(options.gps_jump_fraction, options.gps_jump_m);
    if (options.max_duration_s > 0.0) {
      context.end_ns = context.stamp(options.max_duration_s);
    }
  }

  // Once the robot has stopped at the end of its path, the devices run on for the hold time.
  void notice_stop() {
    if (stop_seen || !motion.finished()) {
      return;
    }
    stop_seen = true;
    context.end_ns =
        std::min(context.end_ns, context.stamp(motion.latest().t_s + options.hold_after_stop_s));
  }

  World world;
  config::RobotSpec robot;
  SimOptions options;
  Scene scene;
  RobotMotion motion;
  detail::SimRmp rmp;
  std::vector<std::unique_ptr<detail::SimLms>> lasers;  // not movable: they own counters
  detail::SimGps gps;
  detail::SimContext context;
  SimStats stats;
  TimestampNs now_ns = 0;
  bool stop_seen = false;
  bool finished = false;
};

namespace {

// The robot, once it is known to have only lasers the simulator can simulate.
const config::RobotSpec& simulable(const config::RobotSpec& robot) {
  config::require_lms2xx_lasers(robot, "the simulator");
  return robot;
}

}  // namespace

Simulation::Simulation(const World& world, const config::RobotSpec& robot,
                       const SimOptions& options)
    : impl_(std::make_unique<Impl>(world, simulable(robot), options)) {}

Simulation::~Simulation() = default;

bool Simulation::step(SimSink& sink) {
  Impl& s = *impl_;
  if (s.finished) {
    return false;
  }
  // The device whose output is due first; ties go to the RMP, then the lasers, then the GPS.
  TimestampNs next = s.rmp.next_event_ns(s.context);
  int who = -1;
  for (std::size_t i = 0; i < s.lasers.size(); ++i) {
    const TimestampNs t = s.lasers[i]->next_event_ns(s.context);
    if (t < next) {
      next = t;
      who = static_cast<int>(i);
    }
  }
  const TimestampNs gps_next = s.gps.next_event_ns(s.context);
  if (gps_next < next) {
    next = gps_next;
    who = static_cast<int>(s.lasers.size());
  }
  if (next == detail::kNever) {
    s.finished = true;
    return false;
  }
  BLOCKMAP_CHECK_MSG(next >= s.now_ns, "simulated time went backwards");
  s.now_ns = next;
  if (who < 0) {
    s.rmp.fire(s.context, sink, s.stats);
  } else if (static_cast<std::size_t>(who) < s.lasers.size()) {
    s.lasers[static_cast<std::size_t>(who)]->fire(s.context, sink, s.stats);
  } else {
    s.gps.fire(s.context, sink, s.stats);
  }
  s.notice_stop();
  return true;
}

void Simulation::run(SimSink& sink) {
  while (step(sink)) {
  }
}

TimestampNs Simulation::start_ns() const noexcept {
  return impl_->context.start_ns;
}
TimestampNs Simulation::now_ns() const noexcept {
  return impl_->now_ns;
}
double Simulation::elapsed_s() const noexcept {
  return impl_->context.seconds(impl_->now_ns);
}
bool Simulation::finished() const noexcept {
  return impl_->finished;
}
const Scene& Simulation::scene() const noexcept {
  return impl_->scene;
}
const RobotMotion& Simulation::motion() const noexcept {
  return impl_->motion;
}
const config::RobotSpec& Simulation::robot() const noexcept {
  return impl_->robot;
}
const World& Simulation::world() const noexcept {
  return impl_->world;
}
const SimStats& Simulation::stats() const noexcept {
  return impl_->stats;
}

std::size_t Simulation::serial_device_count() const noexcept {
  return impl_->lasers.size() + 1;
}

std::string Simulation::serial_device_name(std::size_t device) const {
  if (device < impl_->robot.lasers.size()) {
    return "laser_" + impl_->robot.lasers[device].name;
  }
  return "gps";
}

std::size_t Simulation::memory_bytes() const noexcept {
  std::size_t bytes = sizeof(Impl) + impl_->scene.memory_bytes() + impl_->gps.memory_bytes();
  for (const std::unique_ptr<detail::SimLms>& laser : impl_->lasers) {
    bytes += laser->memory_bytes();
  }
  return bytes;
}

}  // namespace blockmap::hal::sim
