#include "blockmap/hal/sim/loopback_can_bus.hpp"

#include "blockmap/hal/sim/random.hpp"

namespace blockmap::hal::sim {
LoopbackCanBus::LoopbackCanBus(ManualClock& clock, const LoopbackCanConfig& config,
                               std::span<PendingCanFrame> pending_storage,
                               std::span<CanFrame> sent_storage)
    : clock_(clock),
      config_(config),
      random_(config.seed),
      pending_(pending_storage),
      sent_log_(sent_storage) {}

IoStatus LoopbackCanBus::inject(const CanFrame& frame) {
  if (config_.drop_probability > 0.0 && uniform_unit(random_) < config_.drop_probability) {
    drops_.increment();
    return IoStatus::kOk;  // lost on the wire: the sender cannot tell
  }
  const PendingCanFrame pending{frame, clock_.now_ns() + config_.delay_ns};
  if (!pending_.try_push(pending)) {
    return IoStatus::kOverflow;
  }
  if (config_.duplicate_probability > 0.0 &&
      uniform_unit(random_) < config_.duplicate_probability) {
    duplicates_.increment();
    (void)pending_.try_push(pending);
  }
  return IoStatus::kOk;
}

bool LoopbackCanBus::accepted(const CanFrame& frame) const noexcept {
  if (filter_count_ == 0) {
    return true;
  }
  for (std::size_t i = 0; i < filter_count_; ++i) {
    if ((frame.id & filters_[i].mask) == (filters_[i].id & filters_[i].mask)) {
      return true;
    }
  }
  return false;
}

CanReceiveResult LoopbackCanBus::do_receive(CanFrame& frame, TimestampNs /*timeout_ns*/) {
  if (bus_off_) {
    return CanReceiveResult{IoStatus::kDeviceLost, 0};
  }
  // Frames keep their order (one delay for all); filtered ones never reach the socket.
  while (!pending_.empty() && pending_.front().deliver_at_ns <= clock_.now_ns()) {
    PendingCanFrame next;
    (void)pending_.try_pop(next);
    if (accepted(next.frame)) {
      frame = next.frame;
      return CanReceiveResult{IoStatus::kOk, next.deliver_at_ns};
    }
  }
  return CanReceiveResult{IoStatus::kWouldBlock, 0};
}

IoStatus LoopbackCanBus::do_send(const CanFrame& frame) {
  if (bus_off_) {
    return IoStatus::kDeviceLost;
  }
  sent_log_.push_overwrite(frame);
  return IoStatus::kOk;
}

IoStatus LoopbackCanBus::do_set_filters(std::span<const CanFilter> filters) {
  if (filters.size() > kMaxFilters) {
    return IoStatus::kInvalidArgument;
  }
  filter_count_ = filters.size();
  for (std::size_t i = 0; i < filters.size(); ++i) {
    filters_[i] = filters[i];
  }
  return IoStatus::kOk;
}

}  // namespace blockmap::hal::sim
