// What the Linux backends share about waiting on a descriptor and reading clocks (private to
// hal/linux).
#pragma once

#include <ctime>
#include <string>
#include <system_error>

#include "blockmap/core/time.hpp"

namespace blockmap::hal::linux_backend {

// A clock's reading in nanoseconds (CLOCK_MONOTONIC: the base of every stamp here).
inline TimestampNs clock_now_ns(clockid_t clock = CLOCK_MONOTONIC) noexcept {
  timespec now{};
  ::clock_gettime(clock, &now);
  return static_cast<TimestampNs>(now.tv_sec) * kNanosecondsPerSecond +
         static_cast<TimestampNs>(now.tv_nsec);
}

// poll() takes milliseconds: rounded up, so that a short timeout still waits.
inline int poll_timeout_ms(TimestampNs timeout_ns) noexcept {
  if (timeout_ns <= 0) {
    return 0;
  }
  const TimestampNs ms = (timeout_ns + 999'999) / 1'000'000;
  return ms > 1'000'000'000 ? 1'000'000'000 : static_cast<int>(ms);
}

// errno's text, for the one-line errors of open().
inline std::string error_text(int error) {
  return std::error_code(error, std::generic_category()).message();
}

}  // namespace blockmap::hal::linux_backend
