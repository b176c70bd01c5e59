// The simulated Segway RMP: every 10 ms the status group 0x400-0x407 (docs/protocols.md 1.2), with
// wheel odometry that has the tyre-pressure scale error and random slip, a yaw-rate gyro with a
// bias, and the base's own pitch and roll, all through the codec's encoder.
#include <cmath>

#include "sim_devices.hpp"

namespace blockmap::hal::sim::detail {
namespace {

constexpr TimestampNs kCycleNs = 10'000'000;  // the RMP's 100 Hz control cycle
constexpr TimestampNs kFrameGapNs = 250'000;  // an 8-byte frame at 500 kbit/s, with spacing

}  // namespace

SimRmp::SimRmp(const config::BaseSpec& base, std::uint64_t seed)
    : base_(base), sensing_(base), random_(seed, "rmp") {
  codec_.model = base.model;
  codec_.yaw_sign = base.yaw_sign;
}

TimestampNs SimRmp::next_event_ns(const SimContext& context) const noexcept {
  if (next_frame_ < 8) {
    return frames_ns_ + static_cast<TimestampNs>(next_frame_) * kFrameGapNs;
  }
  const TimestampNs next_cycle = context.start_ns + static_cast<TimestampNs>(cycle_ + 1) * kCycleNs;
  return next_cycle > context.end_ns ? kNever : next_cycle;
}

void SimRmp::fire(SimContext& context, SimSink& sink, SimStats& stats) {
  if (next_frame_ >= 8) {
    ++cycle_;
    make_cycle(context, sink, context.start_ns + static_cast<TimestampNs>(cycle_) * kCycleNs);
    ++stats.rmp_cycles;
  }
  sink.on_can_frame(frames_ns_ + static_cast<TimestampNs>(next_frame_) * kFrameGapNs,
                    frames_.frames[next_frame_]);
  ++next_frame_;
}

void SimRmp::make_cycle(SimContext& context, SimSink& sink, TimestampNs cycle_ns) {
  const double t_s = context.seconds(cycle_ns);
  context.motion.advance_to(t_s);
  const RobotState state = context.motion.state_at(t_s);
  sink.on_truth_state(cycle_ns, state);
  const double dt_s = static_cast<double>(kCycleNs) * 1e-9;
  frames_ =
      protocol::segway_rmp::encode_status(sensing_.sense(state, dt_s, cycle_, random_), codec_);
  frames_ns_ = cycle_ns;
  next_frame_ = 0;
}

}  // namespace blockmap::hal::sim::detail
