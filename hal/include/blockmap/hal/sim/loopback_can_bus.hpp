// LoopbackCanBus: a simulated CAN bus between a simulated device and the host, with fault
// injection: frames dropped, duplicated or delayed, and the controller going bus-off. Frames
// the host sends are recorded for tests. Deterministic for a given seed; time from a ManualClock.
// Single-threaded: the simulation drives it.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <span>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/hal/can_bus.hpp"
#include "blockmap/hal/sim/manual_clock.hpp"

namespace blockmap::hal::sim {

struct LoopbackCanConfig {
  std::uint32_t seed = 1;
  double drop_probability = 0.0;
  double duplicate_probability = 0.0;
  TimestampNs delay_ns = 0;  // each frame is delivered this long after it was put on the bus
};

struct PendingCanFrame {
  CanFrame frame;
  TimestampNs deliver_at_ns = 0;
};

class LoopbackCanBus final : public CanBus {
 public:
  static constexpr std::size_t kMaxFilters = 16;

  // `pending_storage` holds frames on their way to the host; `sent_storage` records the host's
  // frames (oldest dropped when full). Both must outlive the bus.
  LoopbackCanBus(ManualClock& clock, const LoopbackCanConfig& config,
                 std::span<PendingCanFrame> pending_storage, std::span<CanFrame> sent_storage);

  // The simulated device puts `frame` on the bus now. kOverflow when the bus buffer is full
  // (counted by pending().rejected_newest()).
  IoStatus inject(const CanFrame& frame);
  void set_bus_off(bool bus_off) noexcept { bus_off_ = bus_off; }

  [[nodiscard]] const RingBufferRef<PendingCanFrame>& pending() const noexcept { return pending_; }
  [[nodiscard]] const RingBufferRef<CanFrame>& sent() const noexcept { return sent_log_; }
  [[nodiscard]] std::uint64_t injected_drops() const noexcept { return drops_.value(); }
  [[nodiscard]] std::uint64_t injected_duplicates() const noexcept { return duplicates_.value(); }

 protected:
  CanReceiveResult do_receive(CanFrame& frame, TimestampNs timeout_ns) override;
  IoStatus do_send(const CanFrame& frame) override;
  IoStatus do_set_filters(std::span<const CanFilter> filters) override;

 private:
  [[nodiscard]] bool accepted(const CanFrame& frame) const noexcept;

  ManualClock& clock_;
  LoopbackCanConfig config_;
  std::minstd_rand random_;
  RingBufferRef<PendingCanFrame> pending_;
  RingBufferRef<CanFrame> sent_log_;
  std::array<CanFilter, kMaxFilters> filters_{};
  std::size_t filter_count_ = 0;
  bool bus_off_ = false;
  MonotonicCounter drops_;
  MonotonicCounter duplicates_;
};

}  // namespace blockmap::hal::sim
