// LibusbBulk: the bulk endpoints of a vendor-specific USB device through libusb-1.0, for a SICK
// TiM (19a2:5001, docs/protocols.md 3.1): the first interface whose endpoints are a bulk IN and a
// bulk OUT is claimed (a kernel driver bound to it is detached first).
//
// The IN endpoint is read with libusb's asynchronous transfers: kInTransfers of them are kept
// in flight, so that the device always has somewhere to put a scan while the reader decodes
// the last one (a TiM sends a telegram of up to 10 KiB every 67 ms); each poll delivers the
// oldest completed one (in the order they were submitted) and submits it again. Their events
// are handled on the calling thread (the device's reader), within the caller's timeout. A
// device unplugged mid-transfer completes them as gone: kDeviceLost, and the owner closes it and
// opens it again (the daemon's watchdog). Each open() takes a new libusb context, which enumerates
// the bus afresh: a device plugged back in is found without a hot-plug monitor (a robot's
// minimal system may run no udev daemon to rebroadcast the kernel's events). IN data is stamped
// with CLOCK_MONOTONIC when its transfer completed. The rare OUT transfers (commands) are
// synchronous.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "blockmap/hal/usb_bulk.hpp"

struct libusb_context;
struct libusb_device_handle;
struct libusb_transfer;

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

  static constexpr std::size_t kInTransfers = 4;
  static constexpr std::size_t kInTransferBytes =
      std::size_t{16} * 1024;  // a multiple of any packet size

 protected:
  ReadResult do_transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_transfer_out(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;

 private:
  // The device with these ids and serial number, opened; none when it is not on the bus.
  libusb_device_handle* open_by_serial(std::uint16_t vendor_id, std::uint16_t product_id,
                                       const std::string& serial);
  // The interface with a bulk IN and a bulk OUT endpoint; false when there is none.
  bool find_bulk_interface(int& interface_number, std::string& error);

  // One IN transfer and its buffer; `done` is set by its callback (on this thread, inside
  // libusb's event handling).
  struct InTransfer {
    libusb_transfer* transfer = nullptr;
    std::vector<std::uint8_t> buffer;
    bool in_flight = false;
    bool done = false;
    TimestampNs stamp_ns = 0;
    std::size_t delivered = 0;  // bytes of a completed transfer already handed out
  };
  static void on_in_done(libusb_transfer* transfer);  // libusb's callback
  [[nodiscard]] bool start_in_transfers(std::string& error);
  void submit(InTransfer& in);
  // Handles libusb's events until `in` is done or `deadline_ns`; false on timeout.
  bool wait_done(const InTransfer& in, TimestampNs deadline_ns);
  void cancel_in_transfers() noexcept;

  libusb_context* context_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  std::array<InTransfer, kInTransfers> in_{};
  std::size_t oldest_ = 0;  // the transfer submitted first among those not yet delivered
  bool lost_ = false;
  int interface_ = -1;
  std::uint8_t in_endpoint_ = 0;
  std::uint8_t out_endpoint_ = 0;
};

}  // namespace blockmap::hal::linux_backend
