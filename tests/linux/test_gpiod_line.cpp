// GPIO lines through libgpiod (hal/linux/gpiod_line.hpp) on a real kernel's GPIO chip. The host
// here has none (docs/design.md): the tests that need one skip there and run in the arm64 guest
// of scripts/guest-test, whose `virt` machine has a PL061 controller (gpiochip0, 8 lines) with
// QEMU's power button wired to line 3.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>

#include "blockmap/hal/linux/gpiod_line.hpp"
#include "blockmap/hal/linux/steady_clock.hpp"
#include "test_units.hpp"

namespace blockmap::hal::linux_backend {
namespace {

using blockmap::testing::kMs;
constexpr std::uint32_t kLedLine = 5;          // free on the virt machine's PL061
constexpr std::uint32_t kPowerButtonLine = 3;  // QEMU's gpio-key: high for 100 ms per press

bool have_gpiochip0() {
  return ::access("/dev/gpiochip0", R_OK | W_OK) == 0;
}

TEST(GpiodLine, AChipThatIsNotThereIsOneLineNamingIt) {
  GpiodLine line;
  const std::string error =
      line.open("gpiochip97", 1, GpioDirection::kOutput, false, "blockmap-test");
  EXPECT_EQ(error.rfind("gpiochip97: cannot open the GPIO chip (", 0), 0u) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
  EXPECT_FALSE(line.is_open());
  bool level = false;
  EXPECT_EQ(line.get(level), IoStatus::kClosed);
  EXPECT_EQ(line.set(true), IoStatus::kClosed);
  EXPECT_EQ(line.wait_edge(kMs).status, IoStatus::kClosed);
}

class GpiodChipTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_gpiochip0()) {
      GTEST_SKIP() << "no /dev/gpiochip0 here (the guest of scripts/guest-test has a PL061)";
    }
  }
};

TEST_F(GpiodChipTest, AnOutputReadsBackWhatWasSetAndIsNotSharedWithAnotherOpener) {
  GpiodLine led;
  ASSERT_EQ(led.open("gpiochip0", kLedLine, GpioDirection::kOutput, false, "blockmap-test", true),
            "");
  bool level = false;
  ASSERT_EQ(led.get(level), IoStatus::kOk);
  EXPECT_TRUE(level) << "the initial level";
  ASSERT_EQ(led.set(false), IoStatus::kOk);
  ASSERT_EQ(led.get(level), IoStatus::kOk);
  EXPECT_FALSE(level);
  ASSERT_EQ(led.set(true), IoStatus::kOk);
  ASSERT_EQ(led.get(level), IoStatus::kOk);
  EXPECT_TRUE(level);
  // An output waits for no edges.
  EXPECT_EQ(led.wait_edge(kMs).status, IoStatus::kInvalidArgument);
  // A second daemon (or gpioset) cannot take the same line: the holder is named.
  GpiodLine other;
  EXPECT_EQ(other.open("/dev/gpiochip0", kLedLine, GpioDirection::kOutput, false, "second"),
            "/dev/gpiochip0 line 5: in use by \"blockmap-test\"");
  led.close();
  EXPECT_EQ(other.open("/dev/gpiochip0", kLedLine, GpioDirection::kOutput, true, "second"), "")
      << "free once closed";
  // Active low: the kernel inverts, the logical level stays what was set.
  ASSERT_EQ(other.set(true), IoStatus::kOk);
  ASSERT_EQ(other.get(level), IoStatus::kOk);
  EXPECT_TRUE(level);
}

TEST_F(GpiodChipTest, ALineTheChipDoesNotHaveIsRefusedWithItsCount) {
  GpiodLine line;
  const std::string error =
      line.open("gpiochip0", 200, GpioDirection::kInputWithEdges, false, "blockmap-test");
  EXPECT_EQ(error.rfind("gpiochip0 line 200: no such line (the chip has ", 0), 0u) << error;
}

TEST_F(GpiodChipTest, AnInputWithoutEdgesTimesOutOnTime) {
  GpiodLine line;
  ASSERT_EQ(line.open("gpiochip0", 6, GpioDirection::kInputWithEdges, false, "blockmap-test"), "");
  const TimestampNs before = SteadyClock{}.now_ns();
  EXPECT_EQ(line.wait_edge(50 * kMs).status, IoStatus::kTimedOut);
  EXPECT_GE(SteadyClock{}.now_ns() - before, 45 * kMs);
  EXPECT_EQ(line.set(true), IoStatus::kInvalidArgument) << "an input is not driven";
}

// The power button of the guest's machine, pressed from outside: scripts/guest-test watches the
// console for the request below and sends `system_powerdown` to QEMU's monitor, which raises
// line 3 for 100 ms. Needs that rig (BLOCKMAP_GUEST_POWER_BUTTON=1, set by guest_hal.sh).
TEST_F(GpiodChipTest, ThePowerButtonsEdgesArriveWithTheKernelsMonotonicStamps) {
  // NOLINTNEXTLINE(concurrency-mt-unsafe): read before any thread starts
  if (std::getenv("BLOCKMAP_GUEST_POWER_BUTTON") == nullptr) {
    GTEST_SKIP() << "nobody to press the button (scripts/guest-test does, in the guest)";
  }
  GpiodLine button;
  ASSERT_EQ(button.open("gpiochip0", kPowerButtonLine, GpioDirection::kInputWithEdges, false,
                        "blockmap-test"),
            "");
  bool level = true;
  ASSERT_EQ(button.get(level), IoStatus::kOk);
  EXPECT_FALSE(level) << "released";
  const TimestampNs asked = SteadyClock{}.now_ns();
  std::printf("guest-request: power-button\n");
  std::fflush(stdout);
  const GpioEdge pressed = button.wait_edge(30'000 * kMs);
  ASSERT_EQ(pressed.status, IoStatus::kOk);
  EXPECT_TRUE(pressed.rising);
  const GpioEdge released = button.wait_edge(5'000 * kMs);
  const TimestampNs now = SteadyClock{}.now_ns();
  ASSERT_EQ(released.status, IoStatus::kOk);
  EXPECT_FALSE(released.rising);
  // The kernel's stamps are on CLOCK_MONOTONIC: between the request and now, in order, about
  // QEMU's 100 ms apart (its virtual clock runs with the host's under TCG).
  EXPECT_GT(pressed.stamp_ns, asked);
  EXPECT_LE(released.stamp_ns, now);
  EXPECT_GT(released.stamp_ns - pressed.stamp_ns, 50 * kMs);
  EXPECT_LT(released.stamp_ns - pressed.stamp_ns, 1000 * kMs);
  EXPECT_EQ(button.edges(), 2u);
  ASSERT_EQ(button.get(level), IoStatus::kOk);
  EXPECT_FALSE(level);
}

}  // namespace
}  // namespace blockmap::hal::linux_backend
