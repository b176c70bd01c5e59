// A SICK TiM over a real USB stack (hal/linux/libusb_bulk.hpp through libusb-1.0). The host here
// has no USB (docs/design.md): there the tests check the one-line error of a device that is not
// on the bus. In the arm64 guest, scripts/guest-test's usb rig (tests/system/guest_hal.sh)
// serves a TiM from tim_gadget on FunctionFS over dummy_hcd, the same kernel's host side
// enumerates it, and libusb opens it as it opens a TiM on the robot.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>
#include <thread>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/linux/libusb_bulk.hpp"
#include "test_units.hpp"

namespace blockmap::hal::linux_backend {
namespace {

using blockmap::testing::kMs;
constexpr std::uint16_t kSick = 0x19a2;
constexpr std::uint16_t kTim = 0x5001;

TEST(LibusbBulk, ADeviceThatIsNotOnTheBusIsOneLineNamingIt) {
  // NOLINTNEXTLINE(concurrency-mt-unsafe): read before any thread starts
  if (std::getenv("BLOCKMAP_GUEST_TIM_UDC") != nullptr) {
    GTEST_SKIP() << "this guest has a TiM on its bus";
  }
  LibusbBulk usb;
  const std::string error = usb.open(kSick, kTim);
  EXPECT_EQ(error.rfind("usb:19a2:5001: ", 0), 0u) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  EXPECT_FALSE(usb.is_open());
  std::array<std::uint8_t, 64> buffer{};
  EXPECT_EQ(usb.transfer_in(buffer, kMs).status, IoStatus::kClosed);
}

// The guest's gadget is bound to its UDC by writing the UDC's name into this file, and
// unbound (unplugged) by writing an empty line.
void plug(const std::string& udc_file, bool plugged) {
  std::ofstream(udc_file) << (plugged ? "dummy_udc.0" : "") << '\n';
}

// Opens the TiM, waiting for the bus to enumerate it.
std::string open_when_enumerated(LibusbBulk& usb) {
  std::string error;
  for (int attempt = 0; attempt < 100; ++attempt) {
    error = usb.open(kSick, kTim);
    if (error.empty()) {
      return error;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return error;
}

TEST(LibusbBulk, ATimsScansArriveOverARealUsbStackAndSurviveAnUnplug) {
  // NOLINTNEXTLINE(concurrency-mt-unsafe): read before any thread starts
  const char* udc = std::getenv("BLOCKMAP_GUEST_TIM_UDC");
  if (udc == nullptr) {
    GTEST_SKIP() << "no TiM gadget here (the guest of scripts/guest-test serves one)";
  }
  LibusbBulk usb;
  ASSERT_EQ(open_when_enumerated(usb), "");
  // Told apart from another TiM by its serial number (guest_hal.sh gives it 18340123).
  LibusbBulk other;
  EXPECT_EQ(other.open(kSick, kTim, "18340999"),
            "usb:19a2:5001:18340999: no such device on the bus (or no permission to open it)");
  usb.close();
  ASSERT_EQ(usb.open(kSick, kTim, "18340123"), "");
  EXPECT_EQ(usb.in_endpoint(), 0x81);
  EXPECT_EQ(usb.out_endpoint(), 0x02);
  SpscQueue<msg::LaserScan, 64> scans;
  devices::TimScanner tim(usb, scans, devices::TimScannerConfig{});
  ASSERT_EQ(tim.start(), IoStatus::kOk);
  // The capture's scans at 15 Hz: 811 beams of 1/3 deg, stamped as they came off the bus.
  std::size_t received = 0;
  TimestampNs last_stamp_ns = 0;
  for (int poll = 0; poll < 400 && received < 20; ++poll) {
    const IoStatus status = tim.poll(500 * kMs);
    ASSERT_TRUE(status == IoStatus::kOk || status == IoStatus::kTimedOut) << to_string(status);
    for (msg::LaserScan scan; scans.try_pop(scan); ++received) {
      EXPECT_EQ(scan.beam_count, 811);
      EXPECT_GT(scan.header.stamp_ns, last_stamp_ns);
      last_stamp_ns = scan.header.stamp_ns;
    }
  }
  ASSERT_GE(received, 20u);
  EXPECT_EQ(tim.decoder().drops().total(), 0u) << "every byte was a whole telegram";
  // Unplugged: the next transfers say the device is gone.
  plug(udc, false);
  IoStatus status = IoStatus::kOk;
  for (int poll = 0; poll < 100 && status != IoStatus::kDeviceLost; ++poll) {
    status = tim.poll(100 * kMs);
    for (msg::LaserScan scan; scans.try_pop(scan);) {
    }
  }
  EXPECT_EQ(status, IoStatus::kDeviceLost);
  usb.close();
  // Plugged back: found again by a fresh enumeration, started again (the TiM forgot), and
  // scanning.
  plug(udc, true);
  ASSERT_EQ(open_when_enumerated(usb), "");
  ASSERT_EQ(tim.start(), IoStatus::kOk);
  std::size_t after = 0;
  for (int poll = 0; poll < 400 && after < 10; ++poll) {
    static_cast<void>(tim.poll(500 * kMs));
    for (msg::LaserScan scan; scans.try_pop(scan); ++after) {
      EXPECT_EQ(scan.beam_count, 811);
    }
  }
  EXPECT_GE(after, 10u);
}

}  // namespace
}  // namespace blockmap::hal::linux_backend
