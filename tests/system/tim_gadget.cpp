// tim_gadget: the device side of a SICK TiM (19a2:5001) on a real USB stack, for the arm64
// guest's system tests. It serves a FunctionFS function (usb_f_fs) that the guest
// binds to dummy_hcd's UDC, so that the same kernel enumerates it as a USB device and libusb
// opens it as it opens a TiM: one vendor-specific interface, a bulk IN and a bulk OUT endpoint.
//
//   tim_gadget FFS_DIR SCANS.bin
//
// FFS_DIR is where the function's FunctionFS is mounted; SCANS.bin is a capture of real TiM
// scan telegrams (any CoLa dialect). Like a TiM it says nothing until "sEN LMDscandata 1"
// arrives on its OUT endpoint, answers "sEA LMDscandata 1", then sends the capture's scans
// again and again as CoLa A telegrams at 15 Hz. Unbound from the UDC (an unplug) it forgets
// that it was asked, as a TiM that lost its power does, and waits for the next start command.
#include <fcntl.h>
#include <linux/usb/ch9.h>
#include <linux/usb/functionfs.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "blockmap/hal/protocol/sick_cola.hpp"

namespace {

namespace cola = blockmap::hal::protocol::sick_cola;

// The descriptors FunctionFS wants: full and high speed, one interface, bulk IN then bulk OUT
// (so ep1 is IN and ep2 is OUT).
struct __attribute__((packed)) Endpoints {
  usb_interface_descriptor interface;
  usb_endpoint_descriptor_no_audio in;
  usb_endpoint_descriptor_no_audio out;
};

struct __attribute__((packed)) Descriptors {
  usb_functionfs_descs_head_v2 header;
  std::uint32_t fs_count;
  std::uint32_t hs_count;
  Endpoints fs;
  Endpoints hs;
};

constexpr char kInterfaceName[] = "SICK TiM (blockmap test gadget)";

struct __attribute__((packed)) Strings {
  usb_functionfs_strings_head header;
  std::uint16_t language;
  char name[sizeof kInterfaceName];
};

Endpoints endpoints(std::uint16_t max_packet_bytes) {
  Endpoints e{};
  e.interface.bLength = sizeof e.interface;
  e.interface.bDescriptorType = USB_DT_INTERFACE;
  e.interface.bNumEndpoints = 2;
  e.interface.bInterfaceClass = USB_CLASS_VENDOR_SPEC;
  e.interface.iInterface = 1;
  for (usb_endpoint_descriptor_no_audio* endpoint : {&e.in, &e.out}) {
    endpoint->bLength = sizeof *endpoint;
    endpoint->bDescriptorType = USB_DT_ENDPOINT;
    endpoint->bmAttributes = USB_ENDPOINT_XFER_BULK;
    endpoint->wMaxPacketSize = max_packet_bytes;  // little-endian hosts only (arm64, x86)
  }
  e.in.bEndpointAddress = 1 | USB_DIR_IN;
  e.out.bEndpointAddress = 2 | USB_DIR_OUT;
  return e;
}

bool write_all(int fd, const void* data, std::size_t size) {
  return ::write(fd, data, size) == static_cast<ssize_t>(size);
}

// The capture's scans as CoLa A telegrams, each one bulk IN write.
std::vector<std::vector<std::uint8_t>> telegrams_of(const char* path) {
  std::ifstream file(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(file)),
                                        std::istreambuf_iterator<char>());
  cola::StaticDecoder<> reader;
  std::vector<std::vector<std::uint8_t>> telegrams;
  std::vector<std::uint8_t> telegram(cola::kDefaultTelegramCapacityBytes);
  std::span<const std::uint8_t> rest(bytes);
  for (;;) {
    const cola::Decoder::Step step = reader.push(rest, 0);
    rest = rest.subspan(step.consumed);
    if (step.scan != nullptr) {
      const std::size_t n = cola::encode_scan(cola::Dialect::kColaA, *step.scan,
                                              cola::ScanTelegramFields{}, telegram);
      telegrams.emplace_back(telegram.begin(), telegram.begin() + static_cast<std::ptrdiff_t>(n));
    }
    if (!step.has_event() && rest.empty()) {
      break;
    }
  }
  return telegrams;
}

std::atomic<bool> enabled{false};
std::atomic<bool> streaming{false};
std::atomic<unsigned> starts{0};

// ep0: the function's events. Disabled or unbound, the "TiM" forgets its start command.
void follow_events(int ep0) {
  usb_functionfs_event event{};
  while (::read(ep0, &event, sizeof event) == static_cast<ssize_t>(sizeof event)) {
    switch (event.type) {
      case FUNCTIONFS_ENABLE:
        enabled = true;
        std::printf("tim_gadget: enabled\n");
        break;
      case FUNCTIONFS_DISABLE:
      case FUNCTIONFS_UNBIND:
      case FUNCTIONFS_SUSPEND:
        enabled = false;
        streaming = false;
        break;
      case FUNCTIONFS_SETUP:
        // No vendor requests: stall (a read for an IN request, a write for an OUT one).
        if ((event.u.setup.bRequestType & USB_DIR_IN) != 0) {
          static_cast<void>(::read(ep0, nullptr, 0));
        } else {
          static_cast<void>(::write(ep0, nullptr, 0));
        }
        break;
      default:
        break;
    }
    std::fflush(stdout);
  }
}

// ep2 (OUT): the host's commands; the start command starts the stream and is answered.
void follow_commands(int out, int in) {
  std::vector<char> buffer(512);
  for (;;) {
    const ssize_t n = ::read(out, buffer.data(), buffer.size());
    if (n <= 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));  // disabled: wait
      continue;
    }
    if (std::string(buffer.data(), static_cast<std::size_t>(n)).find("sEN LMDscandata 1") !=
        std::string::npos) {
      static const char kAnswer[] = "\x02sEA LMDscandata 1\x03";
      static_cast<void>(::write(in, kAnswer, sizeof kAnswer - 1));
      streaming = true;
      ++starts;
      std::printf("tim_gadget: start command %u\n", starts.load());
      std::fflush(stdout);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: tim_gadget FFS_DIR SCANS.bin\n");
    return 2;
  }
  const std::string dir = argv[1];
  const std::vector<std::vector<std::uint8_t>> telegrams = telegrams_of(argv[2]);
  if (telegrams.empty()) {
    std::fprintf(stderr, "tim_gadget: no scans in %s\n", argv[2]);
    return 1;
  }
  const int ep0 = ::open((dir + "/ep0").c_str(), O_RDWR);
  if (ep0 < 0) {
    std::perror("tim_gadget: ep0");
    return 1;
  }
  Descriptors descriptors{};
  descriptors.header.magic = FUNCTIONFS_DESCRIPTORS_MAGIC_V2;
  descriptors.header.length = sizeof descriptors;
  descriptors.header.flags = FUNCTIONFS_HAS_FS_DESC | FUNCTIONFS_HAS_HS_DESC;
  descriptors.fs_count = 3;
  descriptors.hs_count = 3;
  descriptors.fs = endpoints(64);
  descriptors.hs = endpoints(512);
  Strings strings{};
  strings.header.magic = FUNCTIONFS_STRINGS_MAGIC;
  strings.header.length = sizeof strings;
  strings.header.str_count = 1;
  strings.header.lang_count = 1;
  strings.language = 0x0409;
  std::memcpy(strings.name, kInterfaceName, sizeof kInterfaceName);
  if (!write_all(ep0, &descriptors, sizeof descriptors) ||
      !write_all(ep0, &strings, sizeof strings)) {
    std::perror("tim_gadget: descriptors");
    return 1;
  }
  const int in = ::open((dir + "/ep1").c_str(), O_RDWR);
  const int out = ::open((dir + "/ep2").c_str(), O_RDWR);
  if (in < 0 || out < 0) {
    std::perror("tim_gadget: endpoints");
    return 1;
  }
  std::printf("tim_gadget: ready, %zu scans\n", telegrams.size());
  std::fflush(stdout);
  std::thread events(follow_events, ep0);
  std::thread commands(follow_commands, out, in);
  events.detach();
  commands.detach();
  std::size_t next = 0;
  for (;;) {
    if (!streaming) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    const std::vector<std::uint8_t>& telegram = telegrams[next];
    if (::write(in, telegram.data(), telegram.size()) < 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));  // unplugged mid-telegram
      continue;
    }
    next = (next + 1) % telegrams.size();
    std::this_thread::sleep_for(std::chrono::microseconds(66'667));
  }
}
