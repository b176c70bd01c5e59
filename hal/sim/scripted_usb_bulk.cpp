#include "blockmap/hal/sim/scripted_usb_bulk.hpp"

#include <algorithm>
#include <cstring>

#include "blockmap/core/check.hpp"

namespace blockmap::hal::sim {

ScriptedUsbBulk::ScriptedUsbBulk(std::span<const std::uint8_t> script, ManualClock& clock,
                                 std::uint32_t seed, std::size_t max_transfer_bytes,
                                 std::span<std::uint8_t> out_storage)
    : script_(script),
      clock_(clock),
      random_(seed),
      max_transfer_bytes_(max_transfer_bytes),
      sent_(out_storage) {
  BLOCKMAP_CHECK_MSG(max_transfer_bytes > 0, "USB transfers carry at least one byte");
}

ReadResult ScriptedUsbBulk::do_transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) {
  if (!attached_) {
    return ReadResult{IoStatus::kDeviceLost, 0, 0};
  }
  if (finished()) {
    (void)clock_.advance_ns(timeout_ns);  // nothing comes: the transfer times out
    return ReadResult{IoStatus::kTimedOut, 0, 0};
  }
  const std::size_t size = 1 + static_cast<std::size_t>(random_()) % max_transfer_bytes_;
  const std::size_t length = std::min({size, buffer.size(), script_.size() - position_});
  std::memcpy(buffer.data(), script_.data() + position_, length);
  position_ += length;
  return ReadResult{IoStatus::kOk, length, clock_.now_ns()};
}

WriteResult ScriptedUsbBulk::do_transfer_out(std::span<const std::uint8_t> bytes,
                                             TimestampNs /*timeout_ns*/) {
  if (!attached_) {
    return WriteResult{IoStatus::kDeviceLost, 0};
  }
  for (std::uint8_t byte : bytes) {
    sent_.push_overwrite(byte);
  }
  return WriteResult{IoStatus::kOk, bytes.size()};
}

}  // namespace blockmap::hal::sim
