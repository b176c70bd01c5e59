#include "blockmap/hal/linux/libusb_bulk.hpp"

#include <libusb-1.0/libusb.h>

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

IoStatus status_of(int error) noexcept {
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
  return {};
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
  int transferred = 0;
  const int result =
      ::libusb_bulk_transfer(handle_, in_endpoint_, buffer.data(), static_cast<int>(buffer.size()),
                             &transferred, timeout_ms(timeout_ns));
  const TimestampNs stamp_ns = clock_now_ns();
  // A timeout with bytes in hand delivers them: they are as good as any.
  if (transferred > 0 && (result == 0 || result == LIBUSB_ERROR_TIMEOUT)) {
    return ReadResult{IoStatus::kOk, static_cast<std::size_t>(transferred), stamp_ns};
  }
  if (result == LIBUSB_ERROR_PIPE) {
    // A stalled endpoint is cleared, so that the next transfer can run.
    static_cast<void>(::libusb_clear_halt(handle_, in_endpoint_));
  }
  if (result == 0) {
    return ReadResult{IoStatus::kWouldBlock, 0, 0};  // a zero-length packet
  }
  return ReadResult{status_of(result), 0, 0};
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
  return WriteResult{status_of(result), 0};
}

}  // namespace blockmap::hal::linux_backend
