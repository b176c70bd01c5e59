#include <gtest/gtest.h>

#include "blockmap/hal/linux/steady_clock.hpp"
#include "blockmap/hal/sim/manual_clock.hpp"
#include "throwing_check.hpp"

namespace blockmap::hal {
namespace {

TEST(ManualClock, MovesOnlyWhenAdvanced) {
  sim::ManualClock clock(1000);
  const Clock& port = clock;
  EXPECT_EQ(port.now_ns(), 1000);
  EXPECT_EQ(port.now_ns(), 1000);
  EXPECT_EQ(clock.advance_ns(500), 1500);
  clock.set_ns(2000);
  EXPECT_EQ(port.now_ns(), 2000);
}

TEST(ManualClock, RefusesToGoBackwards) {
  blockmap::testing::ThrowOnCheckFailure throw_on_check;
  sim::ManualClock clock(1000);
  EXPECT_THROW(clock.advance_ns(-1), blockmap::testing::CheckFailedError);
  EXPECT_THROW(clock.set_ns(999), blockmap::testing::CheckFailedError);
  EXPECT_EQ(clock.now_ns(), 1000);
}

TEST(SteadyClock, IsMonotonic) {
  linux_backend::SteadyClock clock;
  TimestampNs previous = clock.now_ns();
  EXPECT_GT(previous, 0);
  for (int i = 0; i < 1000; ++i) {
    const TimestampNs now = clock.now_ns();
    ASSERT_GE(now, previous);
    previous = now;
  }
}

}  // namespace
}  // namespace blockmap::hal
