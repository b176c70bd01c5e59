#include "blockmap/hal/linux/steady_clock.hpp"

#include <ctime>

namespace blockmap::hal::linux_backend {

TimestampNs SteadyClock::read_ns() const noexcept {
  timespec now{};
  // CLOCK_MONOTONIC cannot fail with a valid pointer; there is no error to report.
  (void)clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<TimestampNs>(now.tv_sec) * kNanosecondsPerSecond +
         static_cast<TimestampNs>(now.tv_nsec);
}

}  // namespace blockmap::hal::linux_backend
