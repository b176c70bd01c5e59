#include "blockmap/hal/sim/manual_clock.hpp"

#include "blockmap/core/check.hpp"

namespace blockmap::hal::sim {

TimestampNs ManualClock::advance_ns(TimestampNs step_ns) {
  BLOCKMAP_CHECK_MSG(step_ns >= 0, "simulated time cannot go backwards");
  return now_ns_.fetch_add(step_ns, std::memory_order_acq_rel) + step_ns;
}

void ManualClock::set_ns(TimestampNs stamp_ns) {
  BLOCKMAP_CHECK_MSG(stamp_ns >= now_ns_.load(std::memory_order_acquire),
                     "simulated time cannot go backwards");
  now_ns_.store(stamp_ns, std::memory_order_release);
}

}  // namespace blockmap::hal::sim
