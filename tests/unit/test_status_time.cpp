#include <gtest/gtest.h>

#include <set>
#include <string>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/status.hpp"
#include "blockmap/core/time.hpp"

namespace blockmap {
namespace {

TEST(IoStatus, EveryValueHasADistinctStableName) {
  const IoStatus all[] = {IoStatus::kOk,       IoStatus::kWouldBlock,      IoStatus::kTimedOut,
                          IoStatus::kClosed,   IoStatus::kDeviceLost,      IoStatus::kBadData,
                          IoStatus::kOverflow, IoStatus::kInvalidArgument, IoStatus::kIoError};
  std::set<std::string> names;
  for (IoStatus status : all) {
    names.insert(to_string(status));
  }
  EXPECT_EQ(names.size(), std::size(all));
  EXPECT_STREQ(to_string(IoStatus::kWouldBlock), "would_block");
  EXPECT_TRUE(is_ok(IoStatus::kOk));
  EXPECT_FALSE(is_ok(IoStatus::kDeviceLost));
}

TEST(MonotonicCounter, OnlyGrows) {
  MonotonicCounter counter;
  EXPECT_EQ(counter.value(), 0u);
  counter.increment();
  counter.increment(41);
  EXPECT_EQ(counter.value(), 42u);
}

TEST(Time, ConvertsBetweenSecondsAndNanoseconds) {
  EXPECT_EQ(ns_from_seconds(1.5), 1'500'000'000);
  EXPECT_EQ(ns_from_seconds(-0.25), -250'000'000);
  EXPECT_DOUBLE_EQ(seconds_from_ns(2'000'000'001), 2.000000001);
  // A day of nanoseconds survives the round trip to the nanosecond.
  constexpr TimestampNs kDay = 86'400 * kNanosecondsPerSecond + 123;
  EXPECT_EQ(ns_from_seconds(seconds_from_ns(kDay)), kDay);
}

}  // namespace
}  // namespace blockmap
