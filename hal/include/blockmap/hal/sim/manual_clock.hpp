// ManualClock: simulated time, moved forward only by whoever drives the simulation.
#pragma once

#include <atomic>

#include "blockmap/hal/clock.hpp"

namespace blockmap::hal::sim {

class ManualClock final : public Clock {
 public:
  explicit ManualClock(TimestampNs start_ns = 0) noexcept : now_ns_(start_ns) {}

  // Moves time forward by `step_ns` (>= 0); returns the new time. Time never goes backwards,
  // so a negative step is a CHECK failure.
  TimestampNs advance_ns(TimestampNs step_ns);
  // Sets the time to `stamp_ns`, which must not be earlier than now.
  void set_ns(TimestampNs stamp_ns);

 protected:
  [[nodiscard]] TimestampNs read_ns() const noexcept override {
    return now_ns_.load(std::memory_order_acquire);
  }

 private:
  std::atomic<TimestampNs> now_ns_;
};

}  // namespace blockmap::hal::sim
