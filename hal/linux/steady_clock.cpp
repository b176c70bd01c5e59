#include "blockmap/hal/linux/steady_clock.hpp"

#include "descriptor_wait.hpp"

namespace blockmap::hal::linux_backend {

// CLOCK_MONOTONIC cannot fail with a valid pointer; there is no error to report.
TimestampNs SteadyClock::read_ns() const noexcept {
  return clock_now_ns();
}

}  // namespace blockmap::hal::linux_backend
