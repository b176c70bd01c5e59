// Hokuyo SCIP 2.0: worked examples, a real URG-04LX session (../shared, GPL: not shipped),
// encoder round trips, chunking invariance, corruption (docs/protocols.md section 4).
#include "blockmap/hal/protocol/hokuyo_scip2.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "byte_streams.hpp"
#include "test_data.hpp"

namespace blockmap::hal::protocol::hokuyo_scip2 {
namespace {

using blockmap::testing::bytes_of;
using blockmap::testing::Chunking;

struct Decoded {
  std::vector<std::string> replies;  // "echo|status"
  std::vector<msg::LaserScan> scans;
  std::vector<DropReason> rejections;
  SensorParameters sensor;
  std::uint64_t time_ms = 0;
};

Decoded decode(std::span<const std::uint8_t> bytes, Chunking chunking = Chunking::kWhole,
               std::uint32_t seed = 1) {
  Decoder decoder;
  Decoded result;
  blockmap::testing::feed_in_chunks(
      bytes, chunking, seed, [&](std::span<const std::uint8_t> chunk) {
        while (!chunk.empty()) {
          const Decoder::Step step = decoder.push(chunk, 42);
          chunk = chunk.subspan(step.consumed);
          if (step.reply != nullptr) {
            result.replies.push_back(std::string(step.reply->echo) + "|" +
                                     std::string(step.reply->status));
          }
          if (step.scan != nullptr) result.scans.push_back(*step.scan);
          if (step.rejected) result.rejections.push_back(step.reason);
        }
      });
  result.sensor = decoder.sensor();
  result.time_ms = decoder.sensor_time_ms();
  return result;
}

std::string scan_reply(std::string_view echo, std::string_view status, std::uint32_t time_ms,
                       const std::vector<std::uint32_t>& values, bool three_char = true) {
  std::vector<char> out(8192);
  const std::size_t length = encode_scan_reply(out, echo, status, time_ms, values, three_char);
  EXPECT_GT(length, 0u);
  return {out.data(), length};
}

TEST(Scip2, ChecksumAndCharacterCodeWorkedExamples) {
  EXPECT_EQ(checksum("00"), 'P');
  EXPECT_EQ(checksum("01_2"), 'b');
  EXPECT_EQ(checksum("DMAX:5600"), '_');
  EXPECT_EQ(decode_value("0AI"), 1113u);
  EXPECT_EQ(decode_value("01_2"), 7106u);
}

TEST(Scip2, RequestEncodersMatchTheRealSession) {
  char out[32];
  std::size_t n = encode_single_scan_request(out, 46, 722, 1);
  EXPECT_EQ(std::string(out, n), "GD0046072201\n");
  n = encode_continuous_request(out, 44, 725, 1, 0, 0);
  EXPECT_EQ(std::string(out, n), "MD0044072501000\n");
  n = encode_single_scan_request(out, 0, 768, 3, false);
  EXPECT_EQ(std::string(out, n), "GS0000076803\n");
  EXPECT_EQ(encode_single_scan_request(out, 10000, 0, 1), 0u) << "five-digit step";
}

TEST(Scip2, RealUrg04lxSessionDecodesEveryScan) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(session, "vectors/hokuyo_scip2/urg04lx_session_rx_full.txt");
  BLOCKMAP_SHARED_DATA_OR_SKIP(golden, "vectors/hokuyo_scip2/urg04lx_gd_scans_decoded.json");
  const Decoded decoded = decode(blockmap::testing::read_bytes(session));
  const nlohmann::json expected = nlohmann::json::parse(blockmap::testing::read_text(golden));
  EXPECT_TRUE(decoded.rejections.empty()) << "every checksum in the session verifies";
  ASSERT_EQ(decoded.scans.size(), 121u);
  // PP set the geometry.
  EXPECT_EQ(decoded.sensor.front_step, 384u);
  EXPECT_EQ(decoded.sensor.steps_per_turn, 1024u);
  EXPECT_EQ(decoded.sensor.max_range_mm, 5600u);
  const auto& times = expected["timestamps_ms_of_all_121_GD_replies"];
  for (std::size_t i = 0; i < 121; ++i) {
    EXPECT_EQ(decoded.scans[i].scan_counter, times[i].get<std::uint32_t>()) << "scan " << i;
  }
  const msg::LaserScan& first = decoded.scans.front();
  const auto& values = expected["first_scan"];
  ASSERT_EQ(first.beam_count, 677);
  for (std::size_t i = 0; i < 677; ++i) {
    EXPECT_NEAR(first.ranges_m[i], values[i]["range_mm"].get<double>() * 0.001, 1e-6) << i;
    EXPECT_NEAR(first.start_angle_rad + static_cast<double>(i) * first.angle_increment_rad,
                values[i]["angle_rad"].get<double>(), 1e-9)
        << i;
  }
  EXPECT_NEAR(first.scan_period_s, 0.1, 1e-12);
  // The unsupported commands of that firmware answered with error statuses.
  const auto has = [&](const std::string& reply) {
    return std::find(decoded.replies.begin(), decoded.replies.end(), reply) !=
           decoded.replies.end();
  };
  EXPECT_TRUE(has("CR00|03"));
  EXPECT_TRUE(has("HS0|0C"));
  EXPECT_TRUE(has("BM|00"));
  // The SCIP 1.1 "V" reply at the start has no blank line of its own in this log, so it ends
  // with the "SCIP2.0" switch's reply: one legacy reply, status "0".
  EXPECT_TRUE(has("V|0"));
}

TEST(Scip2, RealSessionDoesNotDependOnChunking) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(session, "vectors/hokuyo_scip2/urg04lx_session_rx_first3scans.txt");
  const auto bytes = blockmap::testing::read_bytes(session);
  const Decoded whole = decode(bytes);
  for (const Chunking chunking : {Chunking::kByteByByte, Chunking::kRandom}) {
    const Decoded chunked = decode(bytes, chunking, 7);
    EXPECT_EQ(chunked.replies, whole.replies);
    ASSERT_EQ(chunked.scans.size(), whole.scans.size());
    for (std::size_t s = 0; s < whole.scans.size(); ++s) {
      for (std::size_t i = 0; i < whole.scans[s].beam_count; ++i) {
        ASSERT_EQ(chunked.scans[s].ranges_m[i], whole.scans[s].ranges_m[i]);
      }
    }
  }
}

TEST(Scip2, EncodedScansDecodeBackInBothEncodingsAndAnyChunking) {
  std::vector<std::uint32_t> values;
  for (std::uint32_t i = 0; i < 228; ++i) values.push_back(20 + i * 17 % 4000);
  const std::string stream = scan_reply("GD0044072503", "00", 1234, values) +
                             scan_reply("GS0044072503", "00", 1334, values, false) +
                             scan_reply("MD0044072503001", "00", 0, {}).substr(0, 20) + "\n\n" +
                             scan_reply("MD0044072503000", "99", 1434, values);
  for (const Chunking chunking : {Chunking::kWhole, Chunking::kByteByByte, Chunking::kRandom}) {
    const Decoded decoded = decode(bytes_of(stream), chunking, 3);
    ASSERT_EQ(decoded.scans.size(), 3u);
    EXPECT_TRUE(decoded.rejections.empty());
    for (const msg::LaserScan& scan : decoded.scans) {
      ASSERT_EQ(scan.beam_count, 228);
      EXPECT_NEAR(scan.angle_increment_rad, 3 * 2 * std::numbers::pi / 1024, 1e-12);
      EXPECT_NEAR(scan.start_angle_rad, (44.0 - 384.0) * 2 * std::numbers::pi / 1024, 1e-12);
      for (std::size_t i = 0; i < 228; ++i) {
        ASSERT_FLOAT_EQ(scan.ranges_m[i], static_cast<float>(values[i]) * 0.001F);
        ASSERT_EQ(scan.status[i], msg::BeamStatus::kValid);
      }
    }
    EXPECT_EQ(decoded.scans[2].scan_counter, 1434u);
  }
}

TEST(Scip2, TimestampsAreUnwrappedPastTheTwentyFourBitCounter) {
  const std::vector<std::uint32_t> values(10, 1000);
  const std::string stream = scan_reply("GD0000000901", "00", (1U << 24) - 100, values) +
                             scan_reply("GD0000000901", "00", 50, values) +
                             scan_reply("GD0000000901", "00", 150, values);
  const Decoded decoded = decode(bytes_of(stream));
  ASSERT_EQ(decoded.scans.size(), 3u);
  EXPECT_EQ(decoded.scans[1].scan_counter, (1U << 24) + 50);
  EXPECT_EQ(decoded.time_ms, (1ULL << 24) + 150);
}

TEST(Scip2, ErrorCodesBelowDminAreNotRanges) {
  const std::vector<std::uint32_t> values = {0, 6, 7, 19, 20, 5600, 5601};
  const Decoded decoded = decode(bytes_of(scan_reply("GD0000000601", "00", 1, values)));
  ASSERT_EQ(decoded.scans.size(), 1u);
  const auto& status = decoded.scans[0].status;
  EXPECT_EQ(status[0], msg::BeamStatus::kNoReturn);
  EXPECT_EQ(status[1], msg::BeamStatus::kNoReturn);
  EXPECT_EQ(status[2], msg::BeamStatus::kDeviceError);
  EXPECT_EQ(status[3], msg::BeamStatus::kDeviceError);
  EXPECT_EQ(status[4], msg::BeamStatus::kValid);
  EXPECT_EQ(status[5], msg::BeamStatus::kValid);
  EXPECT_EQ(status[6], msg::BeamStatus::kNoReturn);
}

TEST(Scip2, DamagedRepliesAreDroppedAndTheNextOneDecodes) {
  std::vector<std::uint32_t> values(100, 2000);
  const std::string good = scan_reply("GD0044014301", "00", 500, values);
  std::string bad_checksum = good;
  bad_checksum[30] = bad_checksum[30] == 'A' ? 'B' : 'A';  // inside the first data line
  std::string wrong_count = scan_reply("GD0044014401", "00", 500, values);  // one value short
  const std::string stream = std::string("garbage\n\n") + bad_checksum + wrong_count +
                             good.substr(0, 100) + "\x01" + good.substr(100) + good;
  const Decoded decoded = decode(bytes_of(stream));
  ASSERT_EQ(decoded.scans.size(), 1u);
  EXPECT_EQ(decoded.scans[0].beam_count, 100);
  EXPECT_GE(decoded.rejections.size(), 3u);
}

TEST(Scip2, RandomDamageNeverCrashesAndTheDecoderRecovers) {
  std::vector<std::uint32_t> values(400, 1500);
  std::string stream;
  for (std::uint32_t i = 0; i < 20; ++i)
    stream += scan_reply("MD0044044399000", "99", i * 100, values);
  const auto clean = bytes_of(stream);
  const auto tail = bytes_of(scan_reply("GD0044044301", "00", 9999, values));
  for (std::uint32_t seed = 1; seed <= 30; ++seed) {
    auto damaged =
        seed % 3 == 0 ? blockmap::testing::flip_random_bits(clean, 20, seed)
        : seed % 3 == 1
            ? blockmap::testing::drop_random_bytes(clean, 0.002, seed)
            : blockmap::testing::concat({blockmap::testing::random_garbage(300, seed), clean});
    const Decoded decoded = decode(blockmap::testing::concat({damaged, bytes_of("\n\n"), tail}),
                                   Chunking::kRandom, seed);
    ASSERT_FALSE(decoded.scans.empty()) << "seed " << seed;
    EXPECT_EQ(decoded.scans.back().scan_counter % (1U << 24), 9999u) << "seed " << seed;
    for (const msg::LaserScan& scan : decoded.scans) {
      EXPECT_EQ(scan.beam_count, 400);
    }
  }
}

}  // namespace
}  // namespace blockmap::hal::protocol::hokuyo_scip2
