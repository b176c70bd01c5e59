#include "blockmap/core/status.hpp"

namespace blockmap {

const char* to_string(IoStatus status) noexcept {
  switch (status) {
    case IoStatus::kOk:
      return "ok";
    case IoStatus::kWouldBlock:
      return "would_block";
    case IoStatus::kTimedOut:
      return "timed_out";
    case IoStatus::kClosed:
      return "closed";
    case IoStatus::kDeviceLost:
      return "device_lost";
    case IoStatus::kBadData:
      return "bad_data";
    case IoStatus::kOverflow:
      return "overflow";
    case IoStatus::kInvalidArgument:
      return "invalid_argument";
    case IoStatus::kIoError:
      return "io_error";
  }
  return "unknown";
}

}  // namespace blockmap
