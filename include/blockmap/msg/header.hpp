// What every message carries: when it was received (monotonic ns, stamped by the HAL) and
// which configured device it came from.
#pragma once

#include <cstdint>

#include "blockmap/core/time.hpp"

namespace blockmap::msg {

// Configured per device (for example 1 = Segway base, 2 = horizontal laser, 3 = vertical
// laser, 4 = GPS); 0 means "not set".
using SourceId = std::uint16_t;

struct Header {
  TimestampNs stamp_ns = 0;  // when the first byte of the message arrived (see hal/protocol)
  SourceId source_id = 0;
};

}  // namespace blockmap::msg
