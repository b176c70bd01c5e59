// LibusbBulk: the bulk endpoints of a vendor-specific USB device through libusb-1.0, for a SICK
// TiM (19a2:5001, PROTOCOLS.md 3.1): the first interface whose endpoints are a bulk IN and a
// bulk OUT is claimed (a kernel driver bound to it is detached first).
//
// Transfers are libusb's synchronous ones, each bounded by the caller's timeout: the device's
// reader thread is the only one to wait on them, and libusb runs them as asynchronous
// transfers underneath, so there is nothing a second thread would add. A device unplugged
// mid-transfer reads as kDeviceLost; the owner closes it and opens it again (issue 9's
// watchdog). Each open() takes a new libusb context, which enumerates the bus afresh: a device
// plugged back in is found without a hot-plug monitor (a robot's minimal system may run no
// udev daemon to rebroadcast the kernel's events). IN transfers are stamped with
// CLOCK_MONOTONIC when they completed.
#pragma once

#include <cstdint>
#include <string>

#include "blockmap/hal/usb_bulk.hpp"

struct libusb_context;
struct libusb_device_handle;

namespace blockmap::hal::linux_backend {

class LibusbBulk final : public UsbBulk {
 public:
  LibusbBulk() = default;
  ~LibusbBulk() override;

  // Opens the first device with this vendor and product id, and this serial number unless it
  // is empty (two TiMs on one robot share their ids). Empty when it worked, otherwise one line
  // naming the device and the reason. Closes a device already open first.
  [[nodiscard]] std::string open(std::uint16_t vendor_id, std::uint16_t product_id,
                                 const std::string& serial = {});
  void close() noexcept;
  [[nodiscard]] bool is_open() const noexcept { return handle_ != nullptr; }
  [[nodiscard]] std::uint8_t in_endpoint() const noexcept { return in_endpoint_; }
  [[nodiscard]] std::uint8_t out_endpoint() const noexcept { return out_endpoint_; }

 protected:
  ReadResult do_transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_transfer_out(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;

 private:
  // The device with these ids and serial number, opened; none when it is not on the bus.
  libusb_device_handle* open_by_serial(std::uint16_t vendor_id, std::uint16_t product_id,
                                       const std::string& serial);
  // The interface with a bulk IN and a bulk OUT endpoint; false when there is none.
  bool find_bulk_interface(int& interface_number, std::string& error);

  libusb_context* context_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  int interface_ = -1;
  std::uint8_t in_endpoint_ = 0;
  std::uint8_t out_endpoint_ = 0;
};

}  // namespace blockmap::hal::linux_backend
