#include "blockmap/hal/devices/segway_base.hpp"

#include <array>

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
    // Both samples or neither: the localizer pairs them by stamp.
    if (odometry_.try_push(step.cycle->odometry) && imu_.try_push(step.cycle->imu)) {
      published_.increment();
    } else {
      rejected_.increment();
    }
  }
  return status;
}

}  // namespace blockmap::hal::devices
