// IoStatus: the outcome of one I/O operation on a port (see check.hpp for the three tiers).
// These are expected outcomes on a robot (a cable pulled, a quiet bus), not bugs: callers
// must look at them, hence [[nodiscard]] on the type itself.
#pragma once

#include <cstdint>

namespace blockmap {

enum class [[nodiscard]] IoStatus : std::uint8_t{
    kOk = 0,           // the operation completed
    kWouldBlock,       // nothing to read / no room to write right now; try again later
    kTimedOut,         // a bounded wait ended without data
    kClosed,           // the peer or file ended the stream in an orderly way
    kDeviceLost,       // the device disappeared (unplugged, bus-off, USB detach)
    kBadData,          // bytes arrived but could not be decoded (counted by the codec)
    kOverflow,         // a fixed buffer was full; the policy in the method name applied
    kInvalidArgument,  // the caller passed something the port cannot accept
    kIoError,          // any other operating-system error
};

// A stable lower-case name for logs and JSON, e.g. "would_block".
[[nodiscard]] const char* to_string(IoStatus status) noexcept;

[[nodiscard]] constexpr bool is_ok(IoStatus status) noexcept {
  return status == IoStatus::kOk;
}

}  // namespace blockmap
