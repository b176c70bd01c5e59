#include "blockmap/hal/linux/libusb_bulk.hpp"

#include <libusb-1.0/libusb.h>

#include <sys/time.h>

#include <algorithm>
#include <cstdio>

#include "descriptor_wait.hpp"

namespace blockmap::hal::linux_backend {
namespace {

std::string device_name(std::uint16_t vendor_id, std::uint16_t product_id,
                        const std::string& serial) {
  char name[32];
  std::snprintf(name, sizeof name, "usb:%04x:%04x", vendor_id, product_id);
  return serial.empty() ? std::string(name) : name + (":" + serial);
}

// libusb's milliseconds; 0 would mean "forever" to libusb, so a zero timeout waits 1 ms.
unsigned int timeout_ms(TimestampNs timeout_ns) noexcept {
  const TimestampNs ms = (timeout_ns + 999'999) / 1'000'000;
  if (ms < 1) {
    return 1;
  }
  return ms > 3'600'000 ? 3'600'000U : static_cast<unsigned int>(ms);
}

IoStatus status_of_libusb_error(int error) noexcept {
  switch (error) {
    case LIBUSB_ERROR_NO_DEVICE:
    case LIBUSB_ERROR_NOT_FOUND:
      return IoStatus::kDeviceLost;
    case LIBUSB_ERROR_TIMEOUT:
      return IoStatus::kTimedOut;
    case LIBUSB_ERROR_INVALID_PARAM:
      return IoStatus::kInvalidArgument;
    case LIBUSB_ERROR_OVERFLOW:
      return IoStatus::kOverflow;
    default:
      return IoStatus::kIoError;
  }
}

}  // namespace

LibusbBulk::~LibusbBulk() {
  close();
}

std::string LibusbBulk::open(std::uint16_t vendor_id, std::uint16_t product_id,
                             const std::string& serial) {
  close();
  const std::string name = device_name(vendor_id, product_id, serial);
  if (const int error = ::libusb_init(&context_); error != 0) {
    context_ = nullptr;
    return name + ": libusb cannot start (" + ::libusb_strerror(error) + ")";
  }
  handle_ = serial.empty() ? ::libusb_open_device_with_vid_pid(context_, vendor_id, product_id)
                           : open_by_serial(vendor_id, product_id, serial);
  if (handle_ == nullptr) {
    close();
    return name + ": no such device on the bus (or no permission to open it)";
  }
  int interface_number = -1;
  std::string error;
  if (!find_bulk_interface(interface_number, error)) {
    close();
    return name + ": " + error;
  }
  // A kernel driver (usbserial's generic one, for instance) would hold the interface.
  if (const int attached = ::libusb_kernel_driver_active(handle_, interface_number);
      attached == 1) {
    if (const int detached = ::libusb_detach_kernel_driver(handle_, interface_number);
        detached != 0) {
      close();
      return name + ": a kernel driver holds interface " + std::to_string(interface_number) +
             " and cannot be detached (" + ::libusb_strerror(detached) + ")";
    }
  }
  if (const int claimed = ::libusb_claim_interface(handle_, interface_number); claimed != 0) {
    close();
    return name + ": cannot claim interface " + std::to_string(interface_number) + " (" +
           ::libusb_strerror(claimed) + ")";
  }
  interface_ = interface_number;
  if (!start_in_transfers(error)) {
    close();
    return name + ": " + error;
  }
  return {};
}

void LibusbBulk::on_in_done(libusb_transfer* transfer) {
  auto* in = static_cast<InTransfer*>(transfer->user_data);
  in->done = true;
  in->in_flight = false;
  in->stamp_ns = clock_now_ns();
}

bool LibusbBulk::start_in_transfers(std::string& error) {
  lost_ = false;
  oldest_ = 0;
  for (InTransfer& in : in_) {
    if (in.transfer == nullptr) {
      in.transfer = ::libusb_alloc_transfer(0);
      in.buffer.resize(kInTransferBytes);  // once per object: reopening reuses them
    }
    if (in.transfer == nullptr) {
      error = "libusb cannot allocate a transfer";
      return false;
    }
    ::libusb_fill_bulk_transfer(in.transfer, handle_, in_endpoint_, in.buffer.data(),
                                static_cast<int>(in.buffer.size()), &LibusbBulk::on_in_done, &in,
                                0 /* no timeout: the reader's polls bound the waits */);
    submit(in);
    if (lost_) {
      error = "the device went away as its transfers were submitted";
      return false;
    }
  }
  return true;
}

void LibusbBulk::submit(InTransfer& in) {
  in.done = false;
  in.delivered = 0;
  const int result = ::libusb_submit_transfer(in.transfer);
  in.in_flight = result == 0;
  if (result == LIBUSB_ERROR_NO_DEVICE) {
    lost_ = true;
  }
}

bool LibusbBulk::wait_done(const InTransfer& in, TimestampNs deadline_ns) {
  while (!in.done) {
    if (!in.in_flight) {
      return false;  // never submitted (the device is gone): nothing will complete it
    }
    const TimestampNs left_ns = deadline_ns - clock_now_ns();
    if (left_ns <= 0) {
      return false;
    }
    timeval wait{};
    wait.tv_sec = static_cast<time_t>(left_ns / kNanosecondsPerSecond);
    wait.tv_usec = static_cast<suseconds_t>(
        std::min<TimestampNs>((left_ns % kNanosecondsPerSecond) / 1000 + 1, 999'999));
    const int result = ::libusb_handle_events_timeout_completed(context_, &wait, nullptr);
    if (result != 0 && result != LIBUSB_ERROR_INTERRUPTED) {
      return false;
    }
  }
  return true;
}

void LibusbBulk::cancel_in_transfers() noexcept {
  for (InTransfer& in : in_) {
    if (in.in_flight) {
      static_cast<void>(::libusb_cancel_transfer(in.transfer));
    }
  }
  // A cancelled transfer is finished only when its callback has run: handle the events until
  // every one has (a gone device completes them at once; 2 s is far beyond any).
  const TimestampNs deadline_ns = clock_now_ns() + 2 * kNanosecondsPerSecond;
  for (const InTransfer& in : in_) {
    static_cast<void>(wait_done(in, deadline_ns));
  }
}

libusb_device_handle* LibusbBulk::open_by_serial(std::uint16_t vendor_id, std::uint16_t product_id,
                                                 const std::string& serial) {
  libusb_device** list = nullptr;
  const ssize_t count = ::libusb_get_device_list(context_, &list);
  libusb_device_handle* found = nullptr;
  for (ssize_t i = 0; i < count && found == nullptr; ++i) {
    libusb_device_descriptor descriptor{};
    if (::libusb_get_device_descriptor(list[i], &descriptor) != 0 ||
        descriptor.idVendor != vendor_id || descriptor.idProduct != product_id ||
        descriptor.iSerialNumber == 0) {
      continue;
    }
    libusb_device_handle* handle = nullptr;
    if (::libusb_open(list[i], &handle) != 0) {
      continue;
    }
    unsigned char text[128] = {};
    const int length =
        ::libusb_get_string_descriptor_ascii(handle, descriptor.iSerialNumber, text, sizeof text);
    if (length > 0 &&
        serial == std::string(reinterpret_cast<const char*>(text),  // NOLINT: ASCII bytes
                              static_cast<std::size_t>(length))) {
      found = handle;
    } else {
      ::libusb_close(handle);
    }
  }
  if (list != nullptr) {
    ::libusb_free_device_list(list, 1);
  }
  return found;
}

bool LibusbBulk::find_bulk_interface(int& interface_number, std::string& error) {
  libusb_config_descriptor* config = nullptr;
  if (const int status =
          ::libusb_get_active_config_descriptor(::libusb_get_device(handle_), &config);
      status != 0) {
    error = std::string("cannot read its configuration (") + ::libusb_strerror(status) + ")";
    return false;
  }
  bool found = false;
  for (int i = 0; i < config->bNumInterfaces && !found; ++i) {
    const libusb_interface& interface = config->interface[i];
    if (interface.num_altsetting < 1) {
      continue;
    }
    const libusb_interface_descriptor& setting = interface.altsetting[0];
    std::uint8_t in = 0;
    std::uint8_t out = 0;
    for (int e = 0; e < setting.bNumEndpoints; ++e) {
      const libusb_endpoint_descriptor& endpoint = setting.endpoint[e];
      if ((endpoint.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) != LIBUSB_TRANSFER_TYPE_BULK) {
        continue;
      }
      if ((endpoint.bEndpointAddress & LIBUSB_ENDPOINT_DIR_MASK) == LIBUSB_ENDPOINT_IN) {
        in = in == 0 ? endpoint.bEndpointAddress : in;
      } else {
        out = out == 0 ? endpoint.bEndpointAddress : out;
      }
    }
    if (in != 0 && out != 0) {
      interface_number = setting.bInterfaceNumber;
      in_endpoint_ = in;
      out_endpoint_ = out;
      found = true;
    }
  }
  ::libusb_free_config_descriptor(config);
  if (!found) {
    error = "no interface with a bulk IN and a bulk OUT endpoint";
  }
  return found;
}

void LibusbBulk::close() noexcept {
  cancel_in_transfers();
  for (InTransfer& in : in_) {
    if (in.transfer != nullptr && !in.in_flight) {
      ::libusb_free_transfer(in.transfer);
      in.transfer = nullptr;
    }
    // One still in flight after the wait is left allocated rather than freed under libusb.
  }
  if (handle_ != nullptr) {
    if (interface_ >= 0) {
      static_cast<void>(::libusb_release_interface(handle_, interface_));
    }
    ::libusb_close(handle_);
    handle_ = nullptr;
  }
  interface_ = -1;
  in_endpoint_ = 0;
  out_endpoint_ = 0;
  if (context_ != nullptr) {
    ::libusb_exit(context_);
    context_ = nullptr;
  }
}

ReadResult LibusbBulk::do_transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) {
  if (handle_ == nullptr) {
    return ReadResult{IoStatus::kClosed, 0, 0};
  }
  if (lost_) {
    return ReadResult{IoStatus::kDeviceLost, 0, 0};
  }
  InTransfer& in = in_[oldest_];
  if (!wait_done(in, clock_now_ns() + timeout_ns)) {
    return ReadResult{lost_ ? IoStatus::kDeviceLost : IoStatus::kTimedOut, 0, 0};
  }
  const auto next = [&] {
    submit(in);
    oldest_ = (oldest_ + 1) % kInTransfers;
  };
  switch (in.transfer->status) {
    case LIBUSB_TRANSFER_COMPLETED: {
      const auto length = static_cast<std::size_t>(in.transfer->actual_length);
      const std::size_t bytes = std::min(buffer.size(), length - in.delivered);
      std::copy_n(in.buffer.begin() + static_cast<std::ptrdiff_t>(in.delivered), bytes,
                  buffer.begin());
      in.delivered += bytes;
      const TimestampNs stamp_ns = in.stamp_ns;
      if (in.delivered == length) {
        next();  // all of it handed out: back to the device
      }
      return bytes > 0 ? ReadResult{IoStatus::kOk, bytes, stamp_ns}
                       : ReadResult{IoStatus::kWouldBlock, 0, 0};  // a zero-length packet
    }
    case LIBUSB_TRANSFER_NO_DEVICE:
      lost_ = true;
      return ReadResult{IoStatus::kDeviceLost, 0, 0};
    case LIBUSB_TRANSFER_STALL:
      // A stalled endpoint is cleared, so that the next transfers can run.
      static_cast<void>(::libusb_clear_halt(handle_, in_endpoint_));
      next();
      return ReadResult{IoStatus::kIoError, 0, 0};
    case LIBUSB_TRANSFER_OVERFLOW:
      next();
      return ReadResult{IoStatus::kOverflow, 0, 0};
    default:  // an error, a timeout or a cancellation
      next();
      return ReadResult{lost_ ? IoStatus::kDeviceLost : IoStatus::kIoError, 0, 0};
  }
}

WriteResult LibusbBulk::do_transfer_out(std::span<const std::uint8_t> bytes,
                                        TimestampNs timeout_ns) {
  if (handle_ == nullptr) {
    return WriteResult{IoStatus::kClosed, 0};
  }
  int transferred = 0;
  // libusb takes a non-const pointer for both directions; an OUT transfer only reads it.
  auto* data =
      const_cast<std::uint8_t*>(bytes.data());  // NOLINT(cppcoreguidelines-pro-type-const-cast)
  const int result =
      ::libusb_bulk_transfer(handle_, out_endpoint_, data, static_cast<int>(bytes.size()),
                             &transferred, timeout_ms(timeout_ns));
  if (result == 0 || (result == LIBUSB_ERROR_TIMEOUT && transferred > 0)) {
    return WriteResult{IoStatus::kOk, static_cast<std::size_t>(transferred)};
  }
  if (result == LIBUSB_ERROR_PIPE) {
    static_cast<void>(::libusb_clear_halt(handle_, out_endpoint_));
  }
  return WriteResult{status_of_libusb_error(result), 0};
}

}  // namespace blockmap::hal::linux_backend
