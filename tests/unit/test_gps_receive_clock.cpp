// GPS fixes on the robot's receive clock (FixConverter, FixTime::kReceiveClock): NMEA carries
// UTC, the robot stamps with CLOCK_MONOTONIC, and the fix must land on the monotonic clock at
// the time it was measured, through a serial line that delays each fix by a varying amount.
#include <gtest/gtest.h>

#include "blockmap/hal/gps_observations.hpp"
#include "test_units.hpp"

namespace blockmap::hal {
namespace {

using blockmap::testing::kMs;

// A valid fix measured at `utc_ms_of_day`, received at `received_ns` on the robot's clock.
msg::GpsFix fix_at(std::int32_t utc_ms_of_day, TimestampNs received_ns) {
  msg::GpsFix fix;
  fix.header.stamp_ns = received_ns;
  fix.valid = true;
  fix.has_position = true;
  fix.has_time = true;
  fix.utc_milliseconds_of_day = utc_ms_of_day;
  fix.latitude_deg = 34.02;
  fix.longitude_deg = -118.28;
  return fix;
}

TEST(GpsReceiveClock, TheLeastDelayedFixSetsTheClockAndLaterFixesKeepIt) {
  FixConverter converter(FixTime::kReceiveClock);
  // The monotonic clock read 5,000 s at 12:00:00.000 UTC; each fix takes 80-200 ms to arrive.
  const TimestampNs boot_offset_ns = 5'000'000 * kMs - 43'200'000 * kMs;
  const TimestampNs delays_ms[] = {200, 150, 80, 190, 120, 95};
  localize::GpsObservation observation;
  double up_m = 0.0;
  for (int i = 0; i < 6; ++i) {
    const std::int32_t utc_ms = 43'200'000 + i * 250;
    const TimestampNs received = boot_offset_ns + utc_ms * kMs + delays_ms[i] * kMs;
    ASSERT_TRUE(converter.convert(fix_at(utc_ms, received), 0, observation, up_m));
    // Never later than its receipt: the pipeline's merge has released nothing past it.
    EXPECT_LE(observation.stamp_ns, received);
  }
  // From the third fix on, the clock is the 80 ms one: the last fix at its UTC + 80 ms.
  EXPECT_EQ(converter.receive_delay_ns(), boot_offset_ns + 80 * kMs);
  EXPECT_EQ(observation.stamp_ns, boot_offset_ns + (43'200'000 + 5 * 250) * kMs + 80 * kMs);
  // The 200 ms fix landed 120 ms before its receipt: what the merge must wait for.
  EXPECT_EQ(converter.backdating_ns(), 120 * kMs);
  EXPECT_EQ(FixConverter(FixTime::kUtc).backdating_ns(), 0);
}

TEST(GpsReceiveClock, MidnightKeepsTheClockAndAJumpStartsItOver) {
  FixConverter converter(FixTime::kReceiveClock);
  localize::GpsObservation observation;
  double up_m = 0.0;
  const TimestampNs day_ms = 86'400'000;
  // 23:59:59.750 then 00:00:00.000 of the next day: a quarter second later on the robot.
  const TimestampNs received_before = 1'000'000 * kMs;
  ASSERT_TRUE(converter.convert(fix_at(static_cast<std::int32_t>(day_ms - 250), received_before), 0,
                                observation, up_m));
  const TimestampNs before_ns = observation.stamp_ns;
  ASSERT_TRUE(converter.convert(fix_at(0, received_before + 250 * kMs), 0, observation, up_m));
  EXPECT_EQ(observation.stamp_ns - before_ns, 250 * kMs);
  EXPECT_EQ(converter.clock_restarts(), 0u);
  // The receiver sets its clock 10 s on: the delays start over rather than keep the old one.
  ASSERT_TRUE(converter.convert(fix_at(10'500, received_before + 500 * kMs), 0, observation, up_m));
  EXPECT_EQ(converter.clock_restarts(), 1u);
  EXPECT_EQ(observation.stamp_ns, received_before + 500 * kMs);
}

}  // namespace
}  // namespace blockmap::hal

namespace blockmap::hal {
namespace {

// A 4 Hz receiver whose sentences take 60-400 ms to arrive, and its PPS line: an edge at the
// start of every UTC second, stamped by the kernel on the robot's clock.
struct PpsRun {
  static constexpr TimestampNs kBootOffsetNs = 5'000'000 * kMs - 43'200'000 * kMs;
  std::uint32_t random = 12345;
  TimestampNs delay_ns() {
    random = random * 1'103'515'245U + 12'345U;
    return (60 + static_cast<TimestampNs>((random >> 8) % 341)) * kMs;
  }
  static TimestampNs edge_ns(int second) {
    return kBootOffsetNs + (43'200'000 + static_cast<TimestampNs>(second) * 1000) * kMs;
  }
};

TEST(GpsReceiveClock, PpsEdgesPutEachFixExactlyOnItsSecond) {
  FixConverter with_pps(FixTime::kReceiveClock);
  FixConverter without(FixTime::kReceiveClock);
  PpsRun run;
  localize::GpsObservation a;
  localize::GpsObservation b;
  double up_m = 0.0;
  TimestampNs worst_without_ns = 0;
  for (int second = 0; second < 20; ++second) {
    with_pps.on_pps(PpsRun::edge_ns(second));
    if (second == 7) {
      with_pps.on_pps(PpsRun::edge_ns(second) + 480 * kMs);  // a glitch on the line
    }
    for (int quarter = 0; quarter < 4; ++quarter) {
      const std::int32_t utc_ms = 43'200'000 + second * 1000 + quarter * 250;
      const TimestampNs measured = PpsRun::kBootOffsetNs + utc_ms * kMs;
      const msg::GpsFix fix = fix_at(utc_ms, measured + run.delay_ns());
      ASSERT_TRUE(with_pps.convert(fix, 0, a, up_m));
      ASSERT_TRUE(without.convert(fix, 0, b, up_m));
      EXPECT_EQ(a.stamp_ns, measured) << "second " << second << " quarter " << quarter;
      worst_without_ns = std::max(worst_without_ns, b.stamp_ns - measured);
    }
  }
  EXPECT_EQ(with_pps.pps_fixes(), 80u);
  // Without the pulse the fixes are late by the line's least latency (at least 60 ms here).
  EXPECT_GE(worst_without_ns, 60 * kMs);
}

TEST(GpsReceiveClock, WithoutPulsesTheFixesFallBackOnTheLeastDelay) {
  FixConverter converter(FixTime::kReceiveClock);
  PpsRun run;
  localize::GpsObservation observation;
  double up_m = 0.0;
  for (int second = 0; second < 12; ++second) {
    if (second < 4) {
      converter.on_pps(PpsRun::edge_ns(second));  // then the PPS wire comes off
    }
    const std::int32_t utc_ms = 43'200'000 + second * 1000;
    const TimestampNs measured = PpsRun::kBootOffsetNs + utc_ms * kMs;
    ASSERT_TRUE(converter.convert(fix_at(utc_ms, measured + run.delay_ns()), 0, observation, up_m));
    if (second >= 5) {
      // The old edges are whole seconds away from the estimate: not used.
      EXPECT_EQ(observation.stamp_ns,
                measured + converter.receive_delay_ns() - PpsRun::kBootOffsetNs);
    }
  }
  EXPECT_EQ(converter.pps_fixes(), 4u);
}

}  // namespace
}  // namespace blockmap::hal
