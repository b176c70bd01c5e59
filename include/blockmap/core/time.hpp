// Time as data. The core never reads a clock: every message carries a monotonic timestamp in
// nanoseconds taken by the HAL (hal/include/blockmap/hal/clock.hpp), and algorithms compute
// with differences of those stamps.
#pragma once

#include <cstdint>

namespace blockmap {

// Monotonic nanoseconds since an arbitrary epoch fixed for one run (a boot, a log, a simulation).
using TimestampNs = std::int64_t;

inline constexpr TimestampNs kNanosecondsPerSecond = 1'000'000'000;

[[nodiscard]] constexpr double seconds_from_ns(TimestampNs stamp_ns) noexcept {
  return static_cast<double>(stamp_ns) * 1e-9;
}

// Rounds to the nearest nanosecond.
[[nodiscard]] constexpr TimestampNs ns_from_seconds(double seconds) noexcept {
  const double ns = seconds * 1e9;
  return static_cast<TimestampNs>(ns < 0.0 ? ns - 0.5 : ns + 0.5);
}

}  // namespace blockmap
