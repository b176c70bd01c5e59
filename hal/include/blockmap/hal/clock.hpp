// Clock port: the only place in blockmap where time is read. Device readers stamp every
// message with now_ns() as the bytes arrive; the core computes only with those stamps.
//
// Implementations: linux/steady_clock.hpp (CLOCK_MONOTONIC, on the robot) and
// sim/manual_clock.hpp (advanced by the simulation, so a run is deterministic and can go faster
// than real time).
#pragma once

#include "blockmap/core/time.hpp"

namespace blockmap::hal {

class Clock {
 public:
  Clock() = default;
  Clock(const Clock&) = delete;
  Clock& operator=(const Clock&) = delete;
  virtual ~Clock() = default;

  // Monotonic nanoseconds; never goes backwards. Thread-safe, non-blocking.
  [[nodiscard]] TimestampNs now_ns() const noexcept { return read_ns(); }

 protected:
  [[nodiscard]] virtual TimestampNs read_ns() const noexcept = 0;
};

}  // namespace blockmap::hal
