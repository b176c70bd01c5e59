// ScriptedUsbBulk: a simulated vendor-specific USB device (a SICK TiM) whose bulk IN endpoint
// returns a script in transfers of random size, and whose OUT transfers are recorded. It can be
// unplugged and plugged back (hot-unplug: kDeviceLost until reattached). Single-threaded.
#pragma once

#include <random>
#include <span>

#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/hal/sim/manual_clock.hpp"
#include "blockmap/hal/usb_bulk.hpp"

namespace blockmap::hal::sim {

class ScriptedUsbBulk final : public UsbBulk {
 public:
  ScriptedUsbBulk(std::span<const std::uint8_t> script, ManualClock& clock, std::uint32_t seed,
                  std::size_t max_transfer_bytes, std::span<std::uint8_t> out_storage);

  void set_attached(bool attached) noexcept { attached_ = attached; }
  [[nodiscard]] bool finished() const noexcept { return position_ == script_.size(); }
  [[nodiscard]] const RingBufferRef<std::uint8_t>& sent() const noexcept { return sent_; }

 protected:
  ReadResult do_transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_transfer_out(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;

 private:
  std::span<const std::uint8_t> script_;
  std::size_t position_ = 0;
  ManualClock& clock_;
  std::minstd_rand random_;
  std::size_t max_transfer_bytes_;
  bool attached_ = true;
  RingBufferRef<std::uint8_t> sent_;
};

}  // namespace blockmap::hal::sim
