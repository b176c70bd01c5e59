#include "blockmap/hal/devices/segway_base.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace blockmap::hal::devices {

namespace rmp = protocol::segway_rmp;

SegwayBase::SegwayBase(CanBus& bus, SpscQueueRef<msg::OdometrySample>& odometry,
                       SpscQueueRef<msg::ImuSample>& imu, const SegwayBaseConfig& config)
    : bus_(bus), odometry_(odometry), imu_(imu), config_(config), decoder_(config.rmp) {}

IoStatus SegwayBase::install_filters() {
  // docs/protocols.md 1.1: id 0x400 mask 0x7F8 is the status group; 0x680 the CU status.
  static constexpr std::array<CanFilter, 2> kFilters = {CanFilter{rmp::kStatusFirstId, 0x7F8},
                                                        CanFilter{rmp::kCuStatusId, 0x7FF}};
  return bus_.set_filters(kFilters);
}

IoStatus SegwayBase::poll(TimestampNs timeout_ns) {
  IoStatus status = IoStatus::kWouldBlock;
  for (std::size_t i = 0; i < config_.max_frames_per_poll; ++i) {
    CanFrame frame;
    const CanReceiveResult received = bus_.receive(frame, i == 0 ? timeout_ns : 0);
    if (received.status != IoStatus::kOk) {
      return i == 0 ? received.status : IoStatus::kOk;
    }
    status = IoStatus::kOk;
    const rmp::Decoder::Step step = decoder_.push(frame, received.stamp_ns);
    if (step.cycle == nullptr) {
      continue;
    }
    status_ = step.cycle->status;
    if (!plausible(*step.cycle)) {
      implausible_.increment();
      continue;
    }
    // Both samples or neither: the localizer pairs them by stamp.
    if (odometry_.try_push(step.cycle->odometry) && imu_.try_push(step.cycle->imu)) {
      published_.increment();
    } else {
      rejected_.increment();
    }
  }
  return status;
}

bool SegwayBase::plausible(const rmp::StatusCycle& cycle) noexcept {
  const msg::OdometrySample& odometry = cycle.odometry;
  const msg::ImuSample& imu = cycle.imu;
  const auto within = [](double value, double limit) { return std::abs(value) <= limit; };
  bool ok = within(imu.yaw_rate_radps, config_.max_rate_radps) &&
            within(imu.pitch_rate_radps, config_.max_rate_radps) &&
            within(imu.roll_rate_radps, config_.max_rate_radps) &&
            within(imu.pitch_rad, config_.max_tilt_rad) &&
            within(imu.roll_rad, config_.max_tilt_rad) &&
            within(imu.yaw_rate_radps -
                       (odometry.right_wheel_velocity_mps - odometry.left_wheel_velocity_mps) /
                           config_.track_m,
                   config_.max_wheel_gyro_disagreement_radps);
  if (ok && have_last_ && refused_in_a_row_ < config_.refusals_before_restart) {
    constexpr double kMinStepS = 0.01;  // the RMP's 100 Hz
    const double dt_s = std::max(
        seconds_from_ns(odometry.header.stamp_ns - last_.odometry.header.stamp_ns), kMinStepS);
    const double travel_m = config_.max_speed_mps * dt_s;
    const msg::OdometrySample& before = last_.odometry;
    ok = within(odometry.left_wheel_distance_m - before.left_wheel_distance_m, travel_m) &&
         within(odometry.right_wheel_distance_m - before.right_wheel_distance_m, travel_m) &&
         within(odometry.fore_aft_distance_m - before.fore_aft_distance_m, travel_m);
  }
  if (!ok) {
    ++refused_in_a_row_;
    return false;
  }
  last_ = cycle;
  have_last_ = true;
  refused_in_a_row_ = 0;
  return true;
}

}  // namespace blockmap::hal::devices
