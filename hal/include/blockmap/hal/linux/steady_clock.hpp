// SteadyClock: CLOCK_MONOTONIC, the time base of kernel receive timestamps (SocketCAN's
// SO_TIMESTAMPING, evdev, GPIO edge events), so that stamps from different devices compare.
#pragma once

#include "blockmap/hal/clock.hpp"

namespace blockmap::hal::linux_backend {

class SteadyClock final : public Clock {
 protected:
  [[nodiscard]] TimestampNs read_ns() const noexcept override;
};

}  // namespace blockmap::hal::linux_backend
