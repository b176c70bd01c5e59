// UsbBulk port: bulk endpoints of a vendor-specific USB device (a SICK TiM over libusb).
#pragma once

#include <cstdint>
#include <span>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/status.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/hal/byte_stream.hpp"

namespace blockmap::hal {

class UsbBulk {
 public:
  UsbBulk() = default;
  UsbBulk(const UsbBulk&) = delete;
  UsbBulk& operator=(const UsbBulk&) = delete;
  virtual ~UsbBulk() = default;

  // One bulk IN transfer into `buffer`, waiting at most timeout_ns; kDeviceLost after a detach.
  ReadResult transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns);
  // One bulk OUT transfer.
  WriteResult transfer_out(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns);

  [[nodiscard]] std::uint64_t bytes_in() const noexcept { return bytes_in_.value(); }
  [[nodiscard]] std::uint64_t bytes_out() const noexcept { return bytes_out_.value(); }
  [[nodiscard]] std::uint64_t failures() const noexcept { return failures_.value(); }

 protected:
  virtual ReadResult do_transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) = 0;
  virtual WriteResult do_transfer_out(std::span<const std::uint8_t> bytes,
                                      TimestampNs timeout_ns) = 0;

 private:
  MonotonicCounter bytes_in_;
  MonotonicCounter bytes_out_;
  MonotonicCounter failures_;
};

}  // namespace blockmap::hal
