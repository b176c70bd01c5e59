// The protocol codecs allocate nothing once constructed: whole captures, damaged ones
// included, decode inside EXPECT_NO_ALLOCATIONS. (Reading the capture happens before.)
#include <gtest/gtest.h>

#include <memory>
#include <span>
#include <vector>

#include "blockmap/hal/protocol/hokuyo_scip2.hpp"
#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/hal/protocol/sick_cola.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
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

TEST(ProtocolBudget, SickLms2xxDecodesScansAndDamagedStreamsWithoutAllocating) {
  namespace lms = hal::protocol::sick_lms2xx;
  // A continuous-output stream of every angular variant, and a damaged copy, built first.
  std::array<std::uint8_t, lms::kMaxTelegramBytes> telegram{};
  std::array<std::uint16_t, 401> values{};
  std::vector<std::uint8_t> stream;
  for (std::size_t i = 0; i < 50; ++i) {
    const auto variant = static_cast<lms::AngularVariant>(i % 5);
    const std::size_t count = lms::geometry(variant).value_count;
    for (std::size_t v = 0; v < count; ++v) {
      values[v] = lms::encode_beam(0.5 + 0.01 * static_cast<double>(v), msg::BeamStatus::kValid,
                                   lms::Units::kMm, 13);
    }
    const std::size_t length = lms::encode_measured_values(telegram, std::span(values).first(count),
                                                           lms::Units::kMm, 0x10);
    stream.insert(stream.end(), telegram.begin(),
                  telegram.begin() + static_cast<std::ptrdiff_t>(length));
  }
  const auto damaged = testing::flip_random_bits(stream, 100, 5);
  const std::vector<std::uint8_t>* const streams[] = {&stream, &damaged};
  lms::Decoder decoder;
  std::size_t scans = 0;
  EXPECT_NO_ALLOCATIONS({
    for (const std::vector<std::uint8_t>* bytes : streams) {
      std::span<const std::uint8_t> rest(*bytes);
      for (;;) {
        const auto step = decoder.push(rest, 0);
        rest = rest.subspan(step.consumed);
        scans += step.telegram != nullptr && step.telegram->has_scan ? 1U : 0U;
        if (step.event == lms::Decoder::Event::kNone) {
          break;
        }
      }
      while (decoder.flush().event != lms::Decoder::Event::kNone) {
      }
    }
    // What a simulated scanner does per scan.
    (void)lms::encode_measured_values(telegram, values, lms::Units::kCm, 0x10);
  });
  EXPECT_GT(scans, 50u);
  EXPECT_GT(decoder.drops().value(lms::DropReason::kBadCrc), 0u);
}

TEST(ProtocolBudget, SickColaDecodesAndEncodesScansWithoutAllocating) {
  namespace cola = hal::protocol::sick_cola;
  // Real CoLa B scans, a damaged copy (bad checksums, replays) and CoLa A scans, built first.
  const auto frames =
      testing::read_bytes(testing::project_data("cola/sick_scan_xd_test_pcapng_all16_frames.bin"));
  const auto damaged = testing::flip_random_bits(frames, 40, 7);
  auto decoder = std::make_unique<cola::StaticDecoder<>>();
  auto decoder_a = std::make_unique<cola::StaticDecoder<>>();
  auto out = std::make_unique<std::array<std::uint8_t, cola::kDefaultTelegramCapacityBytes>>();
  std::vector<std::uint8_t> cola_a;
  std::size_t scans = 0;
  const auto decode = [&scans](cola::Decoder& d, std::span<const std::uint8_t> rest) {
    for (;;) {
      const auto step = d.push(rest, 0);
      rest = rest.subspan(step.consumed);
      scans += step.scan != nullptr ? 1U : 0U;
      if (rest.empty() && !step.has_event()) {
        break;
      }
    }
    while (d.flush().has_event()) {
    }
  };
  auto scan = std::make_unique<msg::LaserScan>();
  {
    cola::StaticDecoder<> first;
    *scan = *first.push(std::span(frames).first(3374), 0).scan;
  }
  const std::size_t length = cola::encode_scan(cola::Dialect::kColaA, *scan, {}, *out);
  cola_a.assign(out->begin(), out->begin() + static_cast<std::ptrdiff_t>(length));
  scans = 0;
  EXPECT_NO_ALLOCATIONS({
    for (int pass = 0; pass < 10; ++pass) {
      decode(*decoder, frames);
      decode(*decoder, damaged);
      decode(*decoder_a, cola_a);
      // What a simulated scanner does per scan, and the host's start-up commands.
      (void)cola::encode_scan(cola::Dialect::kColaB, *scan, {}, *out);
      (void)cola::encode_set_access_mode(cola::Dialect::kColaB, cola::kAccessLevelAuthorizedClient,
                                         cola::kAuthorizedClientPasswordHash, *out);
      (void)cola::encode_scan_events(cola::Dialect::kColaA, true, *out);
    }
  });
  EXPECT_GE(scans, 10u * (16u + 1u));
  EXPECT_GT(decoder->drops().value(cola::DropReason::kBadChecksum), 0u);
}

TEST(ProtocolBudget, Scip2DecodesScansWithoutAllocating) {
  namespace scip2 = hal::protocol::hokuyo_scip2;
  const std::vector<std::uint32_t> values(682, 1500);
  std::vector<char> reply(8192);
  const std::size_t length = scip2::encode_scan_reply(reply, "MD0044072501000", "99", 100, values);
  ASSERT_GT(length, 0u);
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(reply.data()),
                                            length);
  scip2::Decoder decoder;
  EXPECT_NO_ALLOCATIONS({
    for (int scan = 0; scan < 200; ++scan) {
      std::span<const std::uint8_t> rest = bytes;
      while (!rest.empty()) rest = rest.subspan(decoder.push(rest, scan).consumed);
    }
  });
  EXPECT_EQ(decoder.scans_decoded(), 200u);
}

}  // namespace
}  // namespace blockmap
