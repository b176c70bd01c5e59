// The protocol codecs allocate nothing once constructed: whole captures, damaged ones
// included, decode inside EXPECT_NO_ALLOCATIONS. (Reading the capture happens before.)
#include <gtest/gtest.h>

#include <span>

#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "byte_streams.hpp"
#include "memory_assertions.hpp"
#include "test_data.hpp"

namespace blockmap {
namespace {

TEST(ProtocolBudget, NmeaDecodesRealAndDamagedLogsWithoutAllocating) {
  const auto log = testing::read_bytes(testing::project_data("nmea/gpsd_furuno_gl_ga.log"));
  const auto damaged = testing::flip_random_bits(log, 200, 3);
  hal::protocol::nmea::Decoder decoder;
  std::size_t sentences = 0;
  EXPECT_NO_ALLOCATIONS({
    for (const auto* bytes : {&log, &damaged}) {
      std::span<const std::uint8_t> rest(*bytes);
      while (!rest.empty()) {
        const auto step = decoder.push(rest, 0);
        rest = rest.subspan(step.consumed);
        sentences += step.sentence != nullptr ? 1U : 0U;
      }
    }
  });
  EXPECT_GT(sentences, 100u);
}

TEST(ProtocolBudget, SegwayRmpAssemblesGroupsWithoutAllocating) {
  namespace rmp = hal::protocol::segway_rmp;
  rmp::StatusCycle cycle;
  cycle.odometry.fore_aft_distance_m = 12.0;
  const rmp::StatusFrames frames = rmp::encode_status(cycle, rmp::Config{});
  rmp::Decoder decoder;
  EXPECT_NO_ALLOCATIONS({
    for (int group = 0; group < 1000; ++group) {
      for (const hal::CanFrame& frame : frames.frames) {
        (void)decoder.push(frame, group);
      }
    }
  });
  EXPECT_EQ(decoder.cycles_decoded(), 1000u);
}

}  // namespace
}  // namespace blockmap
