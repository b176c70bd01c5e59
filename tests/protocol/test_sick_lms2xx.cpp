// SICK LMS 200 / 291 codec: the CRC worked example and documented telegrams, a real B0 capture,
// encode -> decode round trips, chunking invariance and corruption (docs/protocols.md section 2).
#include "blockmap/hal/protocol/sick_lms2xx.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "byte_streams.hpp"
#include "test_data.hpp"
#include "test_units.hpp"

namespace blockmap::hal::protocol::sick_lms2xx {
namespace {

using blockmap::testing::Chunking;
using blockmap::testing::concat;
using Event = Decoder::Event;
using Bytes = std::vector<std::uint8_t>;

using blockmap::testing::kDeg;

Bytes hex(std::string_view text) {
  Bytes bytes;
  std::istringstream in{std::string(text)};
  std::string token;
  while (in >> token) {
    bytes.push_back(static_cast<std::uint8_t>(std::stoul(token, nullptr, 16)));
  }
  return bytes;
}

// Runs an encoder into a full-size buffer and keeps the bytes it wrote.
template <typename Encode>
Bytes encoded(Encode&& encode) {
  Bytes out(kMaxTelegramBytes);
  const std::size_t length = encode(std::span<std::uint8_t>(out));
  out.resize(length);
  return out;
}

// What the decoder reported, copied out of its buffers (which the next push reuses).
struct Seen {
  Event event = Event::kNone;
  std::uint64_t offset = 0;
  DropReason reason = DropReason::kCount;
  std::uint8_t address = 0;
  std::uint8_t command = 0;
  bool has_status = false;
  std::uint8_t status = 0;
  msg::DeviceSeverity severity = msg::DeviceSeverity::kOk;
  Bytes data;
  bool has_scan = false;
  std::uint16_t count_word = 0;
  Units units = Units::kCm;
  AngularVariant variant = AngularVariant::k180Deg1Deg;
  double start_angle_rad = 0.0;
  double angle_increment_rad = 0.0;
  double range_max_m = 0.0;
  std::vector<float> ranges_m;
  std::vector<msg::BeamStatus> beams;
  bool operator==(const Seen&) const = default;
};

struct Decoded {
  std::vector<Seen> events;
  std::array<std::uint64_t, static_cast<std::size_t>(DropReason::kCount)> drops{};
  std::uint64_t acks = 0;
  std::uint64_t naks = 0;

  [[nodiscard]] std::uint64_t drop(DropReason reason) const {
    return drops[static_cast<std::size_t>(reason)];
  }
  [[nodiscard]] std::vector<Seen> of(Event event) const {
    std::vector<Seen> selected;
    for (const Seen& seen : events) {
      if (seen.event == event) {
        selected.push_back(seen);
      }
    }
    return selected;
  }
};

Seen seen_of(const Decoder::Step& step) {
  Seen seen;
  seen.event = step.event;
  seen.offset = step.offset;
  if (step.event == Event::kRejected) {
    seen.reason = step.reason;
  }
  if (step.telegram == nullptr) {
    return seen;
  }
  const Telegram& t = *step.telegram;
  seen.offset = t.start_offset;
  seen.address = t.address;
  seen.command = t.command;
  seen.has_status = t.has_status;
  seen.status = t.status;
  seen.severity = t.device_status.severity;
  seen.data.assign(t.data.begin(), t.data.end());
  seen.has_scan = t.has_scan;
  if (t.has_scan) {
    const msg::LaserScan& scan = t.scan;
    seen.count_word = t.count_word;
    seen.units = t.units;
    seen.variant = t.variant;
    seen.start_angle_rad = scan.start_angle_rad;
    seen.angle_increment_rad = scan.angle_increment_rad;
    seen.range_max_m = scan.range_max_m;
    seen.ranges_m.assign(scan.ranges_m.begin(), scan.ranges_m.begin() + scan.beam_count);
    seen.beams.assign(scan.status.begin(), scan.status.begin() + scan.beam_count);
  }
  return seen;
}

// Feeds `bytes` in `chunking`, each chunk with its own receive stamp, then flushes. Checks on the
// way that every telegram carries the stamp of the chunk that held its STX, and that a step
// without an event has consumed the whole chunk.
Decoded decode(std::span<const std::uint8_t> bytes, Chunking chunking = Chunking::kWhole,
               std::uint32_t seed = 1, const Config& config = {}) {
  auto decoder = std::make_unique<Decoder>(config);
  Decoded result;
  std::vector<std::pair<std::uint64_t, TimestampNs>> chunk_starts;  // offset, stamp
  std::uint64_t fed = 0;
  const auto record = [&](const Decoder::Step& step) {
    if (step.event == Event::kNone) {
      return;
    }
    if (step.telegram != nullptr) {
      TimestampNs expected_ns = -1;
      for (const auto& [offset, stamp_ns] : chunk_starts) {
        expected_ns = offset <= step.telegram->start_offset ? stamp_ns : expected_ns;
      }
      EXPECT_EQ(step.telegram->stamp_ns, expected_ns) << "@" << step.telegram->start_offset;
      EXPECT_EQ(step.telegram->device_status.header.stamp_ns, expected_ns);
      if (step.telegram->has_scan) {
        EXPECT_EQ(step.telegram->scan.header.stamp_ns, expected_ns);
      }
    }
    result.events.push_back(seen_of(step));
  };
  TimestampNs stamp_ns = 0;
  blockmap::testing::feed_in_chunks(bytes, chunking, seed,
                                    [&](std::span<const std::uint8_t> chunk) {
                                      stamp_ns += 1000;
                                      chunk_starts.emplace_back(fed, stamp_ns);
                                      fed += chunk.size();
                                      for (;;) {
                                        const Decoder::Step step = decoder->push(chunk, stamp_ns);
                                        chunk = chunk.subspan(step.consumed);
                                        record(step);
                                        if (step.event == Event::kNone) {
                                          EXPECT_TRUE(chunk.empty());
                                          break;
                                        }
                                      }
                                    });
  for (;;) {
    const Decoder::Step step = decoder->flush();
    record(step);
    if (step.event == Event::kNone) {
      break;
    }
  }
  for (std::size_t r = 0; r < result.drops.size(); ++r) {
    result.drops[r] = decoder->drops().value(static_cast<DropReason>(r));
  }
  result.acks = decoder->acks();
  result.naks = decoder->naks();
  return result;
}

// Beams for a scan: ranges across the measuring range, every few beams a reserved code, and
// random field/reflector flag bits above the range bits (which the decoder must ignore).
struct Beams {
  std::vector<std::uint16_t> words;
  std::vector<double> ranges_m;
  std::vector<msg::BeamStatus> status;
};

Beams make_beams(std::size_t count, Units units, std::uint8_t range_bits, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> range(0.0, range_max_m(units, range_bits));
  std::uniform_int_distribution<unsigned> flags(0, (1U << (16U - range_bits)) - 1U);
  Beams beams;
  for (std::size_t i = 0; i < count; ++i) {
    msg::BeamStatus status = msg::BeamStatus::kValid;
    if (i % 17 == 3) {
      status = msg::BeamStatus::kNoReturn;
    } else if (i % 17 == 7) {
      status = msg::BeamStatus::kDazzled;
    } else if (i % 17 == 11) {
      status = msg::BeamStatus::kDeviceError;
    }
    const double range_m = status == msg::BeamStatus::kValid ? range(random) : 0.0;
    const auto flag_bits = static_cast<std::uint16_t>(flags(random) << range_bits);
    beams.words.push_back(
        static_cast<std::uint16_t>(encode_beam(range_m, status, units, range_bits) | flag_bits));
    beams.ranges_m.push_back(range_m);
    beams.status.push_back(status);
  }
  return beams;
}

Bytes scan_telegram(AngularVariant variant, Units units, std::uint32_t seed,
                    std::uint8_t status = 0x10) {
  const Beams beams = make_beams(geometry(variant).value_count, units, 13, seed);
  return encoded([&](std::span<std::uint8_t> out) {
    return encode_measured_values(out, beams.words, units, status);
  });
}

Bytes mode_reply(std::uint8_t result = 0x00, std::uint8_t address = kReplyAddress) {
  const std::array<std::uint8_t, 1> data = {result};
  return encoded([&](std::span<std::uint8_t> out) {
    return encode_reply(out, command::kSwitchModeReply, data, 0x10, address);
  });
}

// --- CRC and the documented telegrams (docs/protocols.md 2.3, 2.4)

TEST(Lms2xx, CrcWorkedExampleStepByStep) {
  // The table of 2.3: the CRC after each byte of the status request.
  const Bytes request = hex("02 00 01 00 31");
  const std::uint16_t after_each[] = {0x0002, 0x0204, 0x0409, 0x0912, 0x1215};
  for (std::size_t n = 1; n <= request.size(); ++n) {
    EXPECT_EQ(crc16(std::span(request).first(n)), after_each[n - 1]) << n << " bytes";
  }
}

TEST(Lms2xx, NamedRequestsAreTheDocumentedTelegrams) {
  EXPECT_EQ(encoded(encode_status_request), hex("02 00 01 00 31 15 12"));
  EXPECT_EQ(encoded(encode_continuous_output), hex("02 00 02 00 20 24 34 08"));
  EXPECT_EQ(encoded(encode_stop_continuous_output), hex("02 00 02 00 20 25 35 08"));
  EXPECT_EQ(encoded(encode_request_scan), hex("02 00 02 00 30 01 31 18"));
  const auto baud = [](std::uint32_t baud_bps) {
    return encoded([&](std::span<std::uint8_t> out) { return encode_set_baud(out, baud_bps); });
  };
  EXPECT_EQ(baud(38400), hex("02 00 02 00 20 40 50 08"));
  EXPECT_EQ(baud(9600), hex("02 00 02 00 20 42 52 08"));
  EXPECT_EQ(baud(500000), hex("02 00 02 00 20 48 58 08"));
  EXPECT_EQ(encoded([](std::span<std::uint8_t> out) {
              return encode_variant(out, AngularVariant::k180DegHalfDeg);
            }),
            hex("02 00 05 00 3B B4 00 32 00 3B 1F"));
  EXPECT_EQ(mode_reply(), hex("02 80 03 00 A0 00 10 16 0A"));
}

TEST(Lms2xx, RequestsFitTheRequestBuffer) {
  std::array<std::uint8_t, kRequestBufferBytes> out{};
  EXPECT_EQ(encode_installation_mode(out), kRequestBufferBytes);
  EXPECT_EQ(out[4], command::kSwitchMode);
  EXPECT_EQ(std::string(out.begin() + 6, out.begin() + 14), "SICK_LMS");
  for (AngularVariant v :
       {AngularVariant::k180Deg1Deg, AngularVariant::k180DegHalfDeg, AngularVariant::k100Deg1Deg,
        AngularVariant::k100DegHalfDeg, AngularVariant::k100DegQuarterDeg}) {
    ASSERT_EQ(encode_variant(out, v), 11u);
    EXPECT_EQ(out[5] | (out[6] << 8), geometry(v).field_deg);
    EXPECT_EQ(out[7] | (out[8] << 8), geometry(v).resolution_centideg);
  }
}

TEST(Lms2xx, EncodersRefuseWhatTheProtocolCannotCarry) {
  std::array<std::uint8_t, kMaxTelegramBytes> out{};
  EXPECT_EQ(encode_set_baud(out, 115200), 0u);
  EXPECT_FALSE(baud_mode(57600).has_value());
  EXPECT_EQ(baud_mode(19200), mode::kBaud19200);
  EXPECT_EQ(encode_installation_mode(out, "SICK"), 0u);
  EXPECT_EQ(encode_status_request(std::span(out).first(6)), 0u);  // needs 7 bytes
  EXPECT_EQ(encode_status_request(std::span(out).first(7)), 7u);
  EXPECT_EQ(encode_request(out, {}), 0u);  // no command byte
  const std::vector<std::uint16_t> values(402, 100);
  EXPECT_EQ(encode_measured_values(out, values, Units::kMm, 0x10), 0u);
  EXPECT_EQ(encode_measured_values(out, std::span(values).first(401), Units::kMm, 0x10),
            kMaxTelegramBytes);
}

TEST(Lms2xx, MeasuredValuesTelegramSizesAreTheDocumentedOnes) {
  // docs/protocols.md 2.6, default configuration: 181 -> 372, 361 -> 732, 401 -> 812, 101 -> 212,
  // 201 -> 412 bytes [S10].
  const std::pair<AngularVariant, std::size_t> sizes[] = {{AngularVariant::k180Deg1Deg, 372},
                                                          {AngularVariant::k180DegHalfDeg, 732},
                                                          {AngularVariant::k100DegQuarterDeg, 812},
                                                          {AngularVariant::k100Deg1Deg, 212},
                                                          {AngularVariant::k100DegHalfDeg, 412}};
  for (const auto& [variant, bytes] : sizes) {
    EXPECT_EQ(scan_telegram(variant, Units::kMm, 1).size(), bytes) << to_string(variant);
  }
}

// The shared collection's request telegrams (computed from public facts, cross-checked against
// drivers): every line's CRC verifies, every named encoder reproduces its line, and the decoder
// (accepting any address) reads each back.
TEST(Lms2xx, SharedRequestTelegramsMatchTheEncoders) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(path, "vectors/sick_lms200/request_telegrams.txt");
  const auto baud = [](std::uint32_t baud_bps) {
    return encoded([&](std::span<std::uint8_t> out) { return encode_set_baud(out, baud_bps); });
  };
  const auto variant = [](AngularVariant v) {
    return encoded([&](std::span<std::uint8_t> out) { return encode_variant(out, v); });
  };
  const std::pair<std::string, Bytes> named[] = {
      {"status request", encoded(encode_status_request)},
      {"request LMS type", encoded(encode_device_type_request)},
      {"read configuration", encoded(encode_read_configuration)},
      {"38400 Bd", baud(38400)},
      {"19200 Bd", baud(19200)},
      {"9600 Bd", baud(9600)},
      {"500 kBd", baud(500000)},
      {"start continuous", encoded(encode_continuous_output)},
      {"stop continuous", encoded(encode_stop_continuous_output)},
      {"request one scan", encoded(encode_request_scan)},
      {"installation mode",
       encoded([](std::span<std::uint8_t> out) { return encode_installation_mode(out); })},
      {"180 deg / 1.00", variant(AngularVariant::k180Deg1Deg)},
      {"180 deg / 0.50", variant(AngularVariant::k180DegHalfDeg)},
      {"100 deg / 0.25", variant(AngularVariant::k100DegQuarterDeg)},
      {"100 deg / 1.00", variant(AngularVariant::k100Deg1Deg)},
      {"reply to 20 xx", mode_reply()},
      {"RS-485 address 1", mode_reply(0x00, 0x81)},
  };
  Config any_address;
  any_address.require_reply_address = false;
  std::istringstream file(blockmap::testing::read_text(path));
  std::string line;
  std::size_t telegrams = 0;
  std::size_t matched = 0;
  while (std::getline(file, line)) {
    const std::size_t gap = line.find("  ");
    if (line.empty() || line[0] == '#' || gap == std::string::npos ||
        line.find("...") != std::string::npos) {
      continue;
    }
    const std::string label = line.substr(0, gap);
    std::string bytes_text = line.substr(line.find_first_not_of(' ', gap));
    bytes_text = bytes_text.substr(0, bytes_text.find("  "));
    const Bytes bytes = hex(bytes_text);
    ASSERT_GE(bytes.size(), 7u) << line;
    ++telegrams;
    const std::size_t n = bytes.size();
    EXPECT_EQ(crc16(std::span(bytes).first(n - 2)), bytes[n - 2] | (bytes[n - 1] << 8)) << line;
    for (const auto& [name, expected] : named) {
      if (label.find(name) != std::string::npos) {
        EXPECT_EQ(bytes, expected) << line;
        ++matched;
      }
    }
    const Decoded decoded = decode(bytes, Chunking::kWhole, 1, any_address);
    const std::vector<Seen> read = decoded.of(Event::kTelegram);
    // 45 and 41 (field requests) are valid telegrams this codec does not interpret.
    EXPECT_EQ(read.size() + decoded.drop(DropReason::kUnsupported), 1u) << line;
    if (!read.empty()) {
      EXPECT_EQ(read[0].address, bytes[1]) << line;
      EXPECT_EQ(read[0].command, bytes[4]) << line;
    }
  }
  EXPECT_EQ(telegrams, 19u);
  EXPECT_EQ(matched, std::size(named));
}

TEST(Lms2xx, DocumentedReplyAfterItsAck) {
  const Decoded decoded = decode(hex("06 02 80 03 00 A0 00 10 16 0A"));
  ASSERT_EQ(decoded.events.size(), 2u);
  EXPECT_EQ(decoded.events[0].event, Event::kAck);
  EXPECT_EQ(decoded.events[0].offset, 0u);
  const Seen& reply = decoded.events[1];
  EXPECT_EQ(reply.event, Event::kTelegram);
  EXPECT_EQ(reply.offset, 1u);
  EXPECT_EQ(reply.address, 0x80);
  EXPECT_EQ(reply.command, command::kSwitchModeReply);
  EXPECT_TRUE(reply.has_status);
  EXPECT_EQ(reply.status, 0x10);
  EXPECT_EQ(reply.data, hex("00"));
  EXPECT_EQ(reply.severity, msg::DeviceSeverity::kOk);  // 0x10 is not an error (2.7)
  EXPECT_FALSE(reply.has_scan);
  EXPECT_EQ(decoded.acks, 1u);
  EXPECT_EQ(std::accumulate(decoded.drops.begin(), decoded.drops.end(), std::uint64_t{0}), 0u);
}

// --- the real capture (../shared; LGPL, so read from there and never copied into the project)

TEST(Lms2xx, RealB0CaptureDecodesToTheReferenceValues) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(bin, "vectors/sick_lms200/dtu_usick_b0_scan_361_mm.bin");
  BLOCKMAP_SHARED_DATA_OR_SKIP(json, "vectors/sick_lms200/dtu_usick_b0_scan_361_mm.decoded.json");
  const Bytes bytes = blockmap::testing::read_bytes(bin);
  const nlohmann::json reference = nlohmann::json::parse(blockmap::testing::read_text(json));
  ASSERT_EQ(bytes.size(), reference["total_bytes"].get<std::size_t>());

  for (Chunking chunking : {Chunking::kWhole, Chunking::kByteByByte, Chunking::kRandom}) {
    const Decoded decoded = decode(bytes, chunking);
    ASSERT_EQ(decoded.events.size(), 1u);
    const Seen& s = decoded.events[0];
    ASSERT_TRUE(s.has_scan);
    EXPECT_EQ(s.command, command::kMeasuredValues);
    EXPECT_EQ(s.count_word, std::stoul(reference["count_word"].get<std::string>(), nullptr, 16));
    EXPECT_EQ(s.status, std::stoul(reference["status"].get<std::string>(), nullptr, 16));
    EXPECT_EQ(s.severity, msg::DeviceSeverity::kOk);
    EXPECT_STREQ(to_string(s.units), reference["units"].get<std::string>().c_str());
    EXPECT_EQ(s.variant, AngularVariant::k180DegHalfDeg);
    EXPECT_DOUBLE_EQ(s.start_angle_rad, -90.0 * kDeg);
    EXPECT_DOUBLE_EQ(s.angle_increment_rad, 0.5 * kDeg);
    EXPECT_DOUBLE_EQ(s.range_max_m, 8.0);  // mm units, 13-bit mode (2.5)
    const auto& values = reference["values"];
    ASSERT_EQ(s.ranges_m.size(), reference["count"].get<std::size_t>());
    ASSERT_EQ(values.size(), s.ranges_m.size());
    for (std::size_t i = 0; i < values.size(); ++i) {
      EXPECT_EQ(s.beams[i], msg::BeamStatus::kValid) << i;
      EXPECT_FLOAT_EQ(s.ranges_m[i], static_cast<float>(values[i].get<double>() * 0.001)) << i;
    }
    EXPECT_EQ(std::accumulate(decoded.drops.begin(), decoded.drops.end(), std::uint64_t{0}), 0u);
  }
}

// --- measured values: round trips, range codes, variants

TEST(Lms2xx, MeasuredValuesRoundTripForEveryVariantUnitAndRangeMode) {
  std::uint32_t seed = 1;
  for (AngularVariant variant :
       {AngularVariant::k180Deg1Deg, AngularVariant::k180DegHalfDeg, AngularVariant::k100Deg1Deg,
        AngularVariant::k100DegHalfDeg, AngularVariant::k100DegQuarterDeg}) {
    for (Units units : {Units::kCm, Units::kMm}) {
      for (std::uint8_t bits : {std::uint8_t{13}, std::uint8_t{14}, std::uint8_t{15}}) {
        const std::string what = std::string(to_string(variant)) + " " + to_string(units) + " " +
                                 std::to_string(bits) + " bit";
        const VariantGeometry g = geometry(variant);
        const Beams beams = make_beams(g.value_count, units, bits, ++seed);
        const Bytes telegram = encoded([&](std::span<std::uint8_t> out) {
          return encode_measured_values(out, beams.words, units, 0x10);
        });
        Config config;
        config.range_bits = bits;
        const Decoded decoded = decode(telegram, Chunking::kWhole, 1, config);
        ASSERT_EQ(decoded.events.size(), 1u) << what;
        const Seen& s = decoded.events[0];
        ASSERT_TRUE(s.has_scan) << what;
        EXPECT_EQ(s.variant, variant) << what;
        EXPECT_EQ(s.units, units) << what;
        EXPECT_EQ(s.count_word & 0x3FF, g.value_count) << what;
        EXPECT_DOUBLE_EQ(s.range_max_m, range_max_m(units, bits)) << what;
        // Value i at i * resolution - field / 2: the first beam on the right, the middle one
        // straight ahead, the last on the left (x forward, y left, counter-clockwise).
        const double half_field_deg = 0.5 * g.field_deg;
        const auto angle_deg = [&](std::size_t i) {
          return (s.start_angle_rad + static_cast<double>(i) * s.angle_increment_rad) / kDeg;
        };
        EXPECT_NEAR(angle_deg(0), -half_field_deg, 1e-9) << what;
        EXPECT_NEAR(angle_deg(g.value_count / 2), 0.0, 1e-9) << what;
        EXPECT_NEAR(angle_deg(g.value_count - 1), half_field_deg, 1e-9) << what;
        EXPECT_NEAR(s.angle_increment_rad, g.resolution_centideg * 0.01 * kDeg, 1e-12) << what;
        ASSERT_EQ(s.ranges_m.size(), beams.ranges_m.size()) << what;
        const double half_unit_m = 0.5 * metres_per_unit(units);
        for (std::size_t i = 0; i < beams.ranges_m.size(); ++i) {
          ASSERT_EQ(s.beams[i], beams.status[i]) << what << " beam " << i;
          if (beams.status[i] == msg::BeamStatus::kValid) {
            EXPECT_NEAR(s.ranges_m[i], beams.ranges_m[i], half_unit_m + 1e-5) << what << " " << i;
          } else {
            EXPECT_EQ(s.ranges_m[i], 0.0F) << what << " " << i;
          }
        }
      }
    }
  }
}

TEST(Lms2xx, ReservedRangeCodesBecomeBeamStatuses) {
  // docs/protocols.md 2.6 [single: S8]: mask-0 not valid, -1 dazzle, -2 overflow, -4 low SNR, -5
  // read error, -8 value > max; -3, -6 and -7 are not reserved and read as ranges. The 14/15-bit
  // codes follow the same pattern (3FFx / 7FFx).
  using msg::BeamStatus;
  const std::pair<std::uint16_t, BeamStatus> below_mask[] = {
      {0, BeamStatus::kDeviceError}, {1, BeamStatus::kDazzled},     {2, BeamStatus::kDeviceError},
      {3, BeamStatus::kValid},       {4, BeamStatus::kDeviceError}, {5, BeamStatus::kDeviceError},
      {6, BeamStatus::kValid},       {7, BeamStatus::kValid},       {8, BeamStatus::kNoReturn},
      {9, BeamStatus::kValid}};
  for (std::uint8_t bits : {std::uint8_t{13}, std::uint8_t{14}, std::uint8_t{15}}) {
    const auto mask = static_cast<std::uint16_t>((1U << bits) - 1U);
    std::vector<std::uint16_t> words(181, 1234);
    for (std::size_t i = 0; i < std::size(below_mask); ++i) {
      words[i] = static_cast<std::uint16_t>(mask - below_mask[i].first);
    }
    const Bytes telegram = encoded([&](std::span<std::uint8_t> out) {
      return encode_measured_values(out, words, Units::kMm, 0x10);
    });
    Config config;
    config.range_bits = bits;
    const Decoded decoded = decode(telegram, Chunking::kWhole, 1, config);
    ASSERT_EQ(decoded.events.size(), 1u);
    const Seen& s = decoded.events[0];
    for (std::size_t i = 0; i < std::size(below_mask); ++i) {
      EXPECT_EQ(s.beams[i], below_mask[i].second)
          << int{bits} << " bit, code mask-" << below_mask[i].first;
      if (below_mask[i].second == BeamStatus::kValid) {
        EXPECT_FLOAT_EQ(s.ranges_m[i], static_cast<float>((mask - below_mask[i].first) * 0.001));
      }
    }
    EXPECT_FLOAT_EQ(s.ranges_m[180], 1.234F);
  }
}

TEST(Lms2xx, EncodeBeamSaturatesAndMapsStatuses) {
  // 13-bit mm: 8.182 m is the largest plain range (1FF6), anything further is "value > max".
  EXPECT_EQ(encode_beam(2.251, msg::BeamStatus::kValid, Units::kMm, 13), 2251);
  EXPECT_EQ(encode_beam(22.51, msg::BeamStatus::kValid, Units::kCm, 13), 2251);
  EXPECT_EQ(encode_beam(8.182, msg::BeamStatus::kValid, Units::kMm, 13), 0x1FF6);
  EXPECT_EQ(encode_beam(8.3, msg::BeamStatus::kValid, Units::kMm, 13), 0x1FF7);
  EXPECT_EQ(encode_beam(1e300, msg::BeamStatus::kValid, Units::kMm, 15), 0x7FF7);
  EXPECT_EQ(encode_beam(-0.1, msg::BeamStatus::kValid, Units::kMm, 13), 0x1FFF);
  EXPECT_EQ(encode_beam(std::nan(""), msg::BeamStatus::kValid, Units::kMm, 14), 0x3FFF);
  EXPECT_EQ(encode_beam(3.0, msg::BeamStatus::kNoReturn, Units::kMm, 14), 0x3FF7);
  EXPECT_EQ(encode_beam(3.0, msg::BeamStatus::kDazzled, Units::kCm, 13), 0x1FFE);
  EXPECT_EQ(encode_beam(3.0, msg::BeamStatus::kTooClose, Units::kCm, 13), 0x1FFF);
}

TEST(Lms2xx, RangeModeHelpers) {
  // docs/protocols.md 2.5/2.6: modes 00-02 13 bits, 03-05 14, 06 15; 8/16/32 m in mm, x10 in cm.
  EXPECT_EQ(range_bits_of_measuring_mode(0x00), 13);
  EXPECT_EQ(range_bits_of_measuring_mode(0x02), 13);
  EXPECT_EQ(range_bits_of_measuring_mode(0x03), 14);
  EXPECT_EQ(range_bits_of_measuring_mode(0x05), 14);
  EXPECT_EQ(range_bits_of_measuring_mode(0x06), 15);
  EXPECT_FALSE(range_bits_of_measuring_mode(0x3F).has_value());
  EXPECT_DOUBLE_EQ(range_max_m(Units::kMm, 13), 8.0);
  EXPECT_DOUBLE_EQ(range_max_m(Units::kCm, 13), 80.0);
  EXPECT_DOUBLE_EQ(range_max_m(Units::kMm, 14), 16.0);
  EXPECT_DOUBLE_EQ(range_max_m(Units::kMm, 15), 32.0);
  EXPECT_EQ(variant_from_count(361), AngularVariant::k180DegHalfDeg);
  EXPECT_EQ(variant_from_count(101), AngularVariant::k100Deg1Deg);
  EXPECT_FALSE(variant_from_count(360).has_value());
}

TEST(Lms2xx, ConfiguredVariantOverridesTheCountAndRejectsOthers) {
  Config forced;
  forced.variant = AngularVariant::k180Deg1Deg;
  const Decoded matching = decode(scan_telegram(AngularVariant::k180Deg1Deg, Units::kCm, 3),
                                  Chunking::kWhole, 1, forced);
  ASSERT_EQ(matching.of(Event::kTelegram).size(), 1u);
  EXPECT_EQ(matching.events[0].variant, AngularVariant::k180Deg1Deg);
  const Decoded other = decode(scan_telegram(AngularVariant::k100DegHalfDeg, Units::kCm, 3),
                               Chunking::kWhole, 1, forced);
  ASSERT_EQ(other.events.size(), 1u);
  EXPECT_EQ(other.events[0].event, Event::kRejected);
  EXPECT_EQ(other.events[0].reason, DropReason::kMalformed);
}

TEST(Lms2xx, StatusByteSeverity) {
  // docs/protocols.md 2.7: bits 0-2 0 ok .. 4 fatal; 0x10 means nothing known; pollution (0x80) and
  // implausible values (0x40, UNVERIFIED against S9) warn; a restart (0x20) informs.
  using msg::DeviceSeverity;
  EXPECT_EQ(severity_of_status(0x00), DeviceSeverity::kOk);
  EXPECT_EQ(severity_of_status(0x10), DeviceSeverity::kOk);
  EXPECT_EQ(severity_of_status(0x11), DeviceSeverity::kInfo);
  EXPECT_EQ(severity_of_status(0x12), DeviceSeverity::kWarning);
  EXPECT_EQ(severity_of_status(0x13), DeviceSeverity::kError);
  EXPECT_EQ(severity_of_status(0x14), DeviceSeverity::kFatal);
  EXPECT_EQ(severity_of_status(0x30), DeviceSeverity::kInfo);
  EXPECT_EQ(severity_of_status(0x50), DeviceSeverity::kWarning);
  EXPECT_EQ(severity_of_status(0x90), DeviceSeverity::kWarning);
  EXPECT_EQ(severity_of_status(0x93), DeviceSeverity::kError);
  // And a scan carries its status byte's severity.
  const Decoded decoded = decode(scan_telegram(AngularVariant::k180Deg1Deg, Units::kMm, 5, 0x13));
  ASSERT_EQ(decoded.events.size(), 1u);
  EXPECT_EQ(decoded.events[0].status, 0x13);
  EXPECT_EQ(decoded.events[0].severity, DeviceSeverity::kError);
}

TEST(Lms2xx, B0ContentsThatCannotBeAScanAreRejected) {
  const auto b0 = [](const Bytes& data) {
    return encoded([&](std::span<std::uint8_t> out) {
      return encode_reply(out, command::kMeasuredValues, data, 0x10);
    });
  };
  Bytes words(2 + 2 * 181, 0x10);
  const auto with_count_word = [&](std::uint16_t count_word, std::size_t extra = 0) {
    Bytes data = words;
    data[0] = static_cast<std::uint8_t>(count_word & 0xFF);
    data[1] = static_cast<std::uint8_t>(count_word >> 8);
    data.resize(data.size() + extra, 0x00);
    return b0(data);
  };
  const auto reason_of = [](const Bytes& telegram) {
    const Decoded decoded = decode(telegram);
    EXPECT_EQ(decoded.events.size(), 1u);
    return decoded.events.empty() ? DropReason::kCount : decoded.events[0].reason;
  };
  EXPECT_EQ(reason_of(with_count_word(180 | 0x4000)), DropReason::kMalformed);     // LEN too long
  EXPECT_EQ(reason_of(with_count_word(182 | 0x4000)), DropReason::kMalformed);     // LEN too short
  EXPECT_EQ(reason_of(with_count_word(181 | 0x8000)), DropReason::kMalformed);     // units 10
  EXPECT_EQ(reason_of(with_count_word(181 | 0x4000, 3)), DropReason::kMalformed);  // 3 extra
  EXPECT_EQ(reason_of(b0({})), DropReason::kMalformed);                            // no count
  // Up to two index bytes between the values and the status are accepted (2.6, S7).
  const Decoded indexed = decode(with_count_word(181 | 0x4000, 2));
  ASSERT_EQ(indexed.of(Event::kTelegram).size(), 1u);
  EXPECT_TRUE(indexed.events[0].has_scan);
  // An interlaced partial scan (bit 13) is valid but not interpreted: counted, not reported.
  const Decoded partial = decode(with_count_word(181 | 0x4000 | 0x2000));
  EXPECT_TRUE(partial.events.empty());
  EXPECT_EQ(partial.drop(DropReason::kUnsupported), 1u);
}

TEST(Lms2xx, UnknownRepliesAreCountedNotReported) {
  const std::array<std::uint8_t, 3> data = {1, 2, 3};
  const Bytes c5 =
      encoded([&](std::span<std::uint8_t> out) { return encode_reply(out, 0xC5, data, 0x10); });
  const Decoded decoded = decode(concat({c5, mode_reply()}));
  ASSERT_EQ(decoded.events.size(), 1u);
  EXPECT_EQ(decoded.events[0].command, command::kSwitchModeReply);
  EXPECT_EQ(decoded.drop(DropReason::kUnsupported), 1u);
  EXPECT_EQ(decoded.drop(DropReason::kGarbage), 0u);
}

TEST(Lms2xx, ReplyAddressIsCheckedUnlessConfiguredOff) {
  const Bytes other_scanner = mode_reply(0x00, 0x81);
  const Decoded strict = decode(other_scanner);
  EXPECT_TRUE(strict.events.empty());
  EXPECT_EQ(strict.drop(DropReason::kGarbage), other_scanner.size());
  Config any_address;
  any_address.require_reply_address = false;
  const Decoded lenient = decode(other_scanner, Chunking::kWhole, 1, any_address);
  ASSERT_EQ(lenient.events.size(), 1u);
  EXPECT_EQ(lenient.events[0].address, 0x81);
  // A host request has no status byte.
  const Decoded request = decode(encoded(encode_request_scan), Chunking::kWhole, 1, any_address);
  ASSERT_EQ(request.events.size(), 1u);
  EXPECT_FALSE(request.events[0].has_status);
  EXPECT_EQ(request.events[0].command, command::kRequestValues);
  EXPECT_EQ(request.events[0].data, hex("01"));
}

TEST(Lms2xx, AcksAndNaksBetweenTelegrams) {
  const Bytes stream = concat({hex("06"), mode_reply(), hex("15 15 06"),
                               scan_telegram(AngularVariant::k180Deg1Deg, Units::kCm, 9)});
  const Decoded decoded = decode(stream);
  std::vector<Event> kinds;
  for (const Seen& seen : decoded.events) {
    kinds.push_back(seen.event);
  }
  EXPECT_EQ(kinds, (std::vector<Event>{Event::kAck, Event::kTelegram, Event::kNak, Event::kNak,
                                       Event::kAck, Event::kTelegram}));
  EXPECT_EQ(decoded.events[2].offset, 10u);
  EXPECT_EQ(decoded.acks, 2u);
  EXPECT_EQ(decoded.naks, 2u);
}

// --- stamps, chunking, corruption

TEST(Lms2xx, StampIsTheArrivalOfTheStx) {
  Decoder decoder;
  const Bytes reply = mode_reply();
  EXPECT_EQ(decoder.push(std::span(reply).first(3), 111).event, Event::kNone);
  const Decoder::Step step = decoder.push(std::span(reply).subspan(3), 222);
  ASSERT_EQ(step.event, Event::kTelegram);
  EXPECT_EQ(step.consumed, reply.size() - 3);
  EXPECT_EQ(step.telegram->stamp_ns, 111);
}

TEST(Lms2xx, TelegramFoundInsideRejectedBytesKeepsItsOwnStamp) {
  // A false header (plausible LEN 64) in noise, then a real reply in a later chunk: the real
  // telegram is read back out of the rejected candidate with the later chunk's stamp.
  Decoder decoder;
  const Bytes noise = hex("02 80 40 00 11 22");
  const Bytes rest = concat({mode_reply(), Bytes(70, 0x33)});
  EXPECT_EQ(decoder.push(noise, 100).event, Event::kNone);
  std::span<const std::uint8_t> chunk(rest);
  std::vector<Decoder::Step> steps;
  for (;;) {
    const Decoder::Step step = decoder.push(chunk, 200);
    chunk = chunk.subspan(step.consumed);
    if (step.event == Event::kNone) {
      break;
    }
    steps.push_back(step);
    if (step.event == Event::kTelegram) {
      EXPECT_EQ(step.telegram->stamp_ns, 200);
      EXPECT_EQ(step.telegram->start_offset, noise.size());
    }
  }
  ASSERT_EQ(steps.size(), 2u);
  EXPECT_EQ(steps[0].event, Event::kRejected);
  EXPECT_EQ(steps[0].reason, DropReason::kBadCrc);
  EXPECT_EQ(steps[0].offset, 0u);
  EXPECT_EQ(steps[1].event, Event::kTelegram);
  EXPECT_EQ(steps[1].consumed, 0u);  // read from bytes consumed before
}

Bytes mixed_stream(std::uint32_t seed) {
  Bytes stream;
  std::mt19937 random(seed);
  const AngularVariant variants[] = {AngularVariant::k180Deg1Deg, AngularVariant::k180DegHalfDeg,
                                     AngularVariant::k100Deg1Deg, AngularVariant::k100DegHalfDeg,
                                     AngularVariant::k100DegQuarterDeg};
  for (std::uint32_t i = 0; i < 12; ++i) {
    const Bytes scan =
        scan_telegram(variants[i % 5], i % 2 == 0 ? Units::kMm : Units::kCm, seed * 100 + i);
    stream = concat({stream, hex("06"), mode_reply(static_cast<std::uint8_t>(i % 3)), scan});
    if (i % 4 == 1) {
      stream = concat({stream, blockmap::testing::random_garbage(40 + i, seed + i)});
    }
  }
  return stream;
}

TEST(Lms2xx, ResultDoesNotDependOnChunking) {
  for (std::uint32_t damage = 0; damage < 3; ++damage) {
    Bytes stream = mixed_stream(7);
    if (damage == 1) {
      stream = blockmap::testing::flip_random_bits(stream, 30, 11);
    } else if (damage == 2) {
      stream = blockmap::testing::drop_random_bytes(stream, 0.003, 12);
    }
    const Decoded whole = decode(stream, Chunking::kWhole);
    ASSERT_FALSE(whole.of(Event::kTelegram).empty()) << damage;
    if (damage == 0) {
      EXPECT_EQ(whole.of(Event::kTelegram).size(), 24u);
    }
    const Decoded single = decode(stream, Chunking::kByteByByte);
    EXPECT_EQ(single.events, whole.events) << damage;
    EXPECT_EQ(single.drops, whole.drops) << damage;
    for (std::uint32_t seed = 1; seed <= 5; ++seed) {
      const Decoded random = decode(stream, Chunking::kRandom, seed);
      EXPECT_EQ(random.events, whole.events) << damage << " seed " << seed;
      EXPECT_EQ(random.drops, whole.drops) << damage << " seed " << seed;
      EXPECT_EQ(random.naks, whole.naks) << damage << " seed " << seed;
    }
  }
}

TEST(Lms2xx, FalseStxInGarbageDoesNotHideTheTelegramsInsideIt) {
  const Bytes scan = scan_telegram(AngularVariant::k180DegHalfDeg, Units::kMm, 21);
  const Bytes reply = mode_reply();
  // A false header claiming the longest telegram, directly before real ones that it covers; a
  // second one with an impossible LEN; a stray STX before the real STX.
  const Bytes later = scan_telegram(AngularVariant::k180DegHalfDeg, Units::kCm, 22);
  const Bytes stream = concat(
      {hex("55 02 80 26 03 AA"), reply, scan, hex("02 80 FF FF"), reply, hex("02"), reply, later});
  for (Chunking chunking : {Chunking::kWhole, Chunking::kByteByByte, Chunking::kRandom}) {
    const Decoded decoded = decode(stream, chunking);
    const std::vector<Seen> telegrams = decoded.of(Event::kTelegram);
    ASSERT_EQ(telegrams.size(), 5u);
    EXPECT_EQ(telegrams[0].offset, 6u);
    EXPECT_TRUE(telegrams[1].has_scan);
    EXPECT_EQ(telegrams[1].offset, 6u + reply.size());
    EXPECT_EQ(decoded.drop(DropReason::kBadCrc), 1u);     // the false 812-byte candidate
    EXPECT_EQ(decoded.drop(DropReason::kBadLength), 1u);  // 02 80 FF FF
    const std::vector<Seen> rejected = decoded.of(Event::kRejected);
    ASSERT_EQ(rejected.size(), 2u);
    EXPECT_EQ(rejected[0].offset, 1u);
    EXPECT_EQ(rejected[0].reason, DropReason::kBadCrc);
  }
}

TEST(Lms2xx, CutOffTelegramThenAGoodOne) {
  const Bytes first = scan_telegram(AngularVariant::k180DegHalfDeg, Units::kMm, 31);
  const Bytes second = scan_telegram(AngularVariant::k180DegHalfDeg, Units::kMm, 32);
  const Bytes stream = concat({std::span(first).first(300), second, mode_reply()});
  for (Chunking chunking : {Chunking::kWhole, Chunking::kByteByByte, Chunking::kRandom}) {
    const Decoded decoded = decode(stream, chunking);
    const std::vector<Seen> telegrams = decoded.of(Event::kTelegram);
    ASSERT_EQ(telegrams.size(), 2u);
    EXPECT_EQ(telegrams[0].offset, 300u);
    EXPECT_EQ(telegrams[0].data, decode(second).events.at(0).data);
    EXPECT_EQ(telegrams[1].command, command::kSwitchModeReply);
    EXPECT_EQ(decoded.drop(DropReason::kBadCrc), 1u);
  }
}

TEST(Lms2xx, TelegramCutOffAtTheEndIsTruncated) {
  const Bytes reply = mode_reply();
  const Bytes stream = concat({reply, std::span(reply).first(5)});
  const Decoded decoded = decode(stream);
  ASSERT_EQ(decoded.events.size(), 2u);
  EXPECT_EQ(decoded.events[1].event, Event::kRejected);
  EXPECT_EQ(decoded.events[1].reason, DropReason::kTruncated);
  EXPECT_EQ(decoded.events[1].offset, reply.size());
  EXPECT_EQ(decoded.drop(DropReason::kTruncated), 1u);
  EXPECT_EQ(decoded.drop(DropReason::kGarbage), 4u);  // the cut-off bytes after its STX
}

TEST(Lms2xx, CountersSayWhatWasDropped) {
  Bytes damaged = mode_reply();
  damaged[5] ^= 0x01;  // the result byte: bad CRC, and none of its bytes is 02, 06 or 15
  const Bytes unknown = encoded([](std::span<std::uint8_t> out) {
    return encode_reply(out, 0xC5, std::span<const std::uint8_t>(), 0x10);
  });
  Bytes short_b0 = encoded([](std::span<std::uint8_t> out) {
    const std::array<std::uint8_t, 4> data = {181, 0x40, 0x00, 0x01};  // 181 values promised
    return encode_reply(out, command::kMeasuredValues, data, 0x10);
  });
  const Bytes stream = concat({hex("11 22 33 44 55"), damaged, hex("02 80 00 00"), short_b0,
                               unknown, mode_reply(), hex("02 80 03")});
  const Decoded decoded = decode(stream);
  EXPECT_EQ(decoded.drop(DropReason::kGarbage), 5u + (damaged.size() - 1) + 3u + 2u);
  EXPECT_EQ(decoded.drop(DropReason::kBadCrc), 1u);
  EXPECT_EQ(decoded.drop(DropReason::kBadLength), 1u);  // LEN 0: not even a command byte
  EXPECT_EQ(decoded.drop(DropReason::kMalformed), 1u);
  EXPECT_EQ(decoded.drop(DropReason::kUnsupported), 1u);
  EXPECT_EQ(decoded.drop(DropReason::kTruncated), 1u);
  ASSERT_EQ(decoded.of(Event::kTelegram).size(), 1u);
  EXPECT_EQ(decoded.of(Event::kRejected).size(), 4u);
}

TEST(Lms2xx, DamagedStreamsNeverCrashAndTheNextGoodTelegramDecodes) {
  const Bytes stream = mixed_stream(3);
  const Bytes good = scan_telegram(AngularVariant::k100DegQuarterDeg, Units::kMm, 77);
  const std::vector<float> good_ranges = decode(good).events.at(0).ranges_m;
  for (std::uint32_t seed = 1; seed <= 40; ++seed) {
    Bytes damaged = (seed % 2 == 0) ? blockmap::testing::flip_random_bits(stream, 40, seed)
                                    : blockmap::testing::drop_random_bytes(stream, 0.01, seed);
    damaged.resize(damaged.size() - seed * 37 % 500);  // cut off mid-telegram
    const Decoded decoded = decode(concat({damaged, good}), Chunking::kRandom, seed);
    const std::vector<Seen> telegrams = decoded.of(Event::kTelegram);
    ASSERT_FALSE(telegrams.empty()) << "seed " << seed;
    EXPECT_EQ(telegrams.back().offset, damaged.size()) << "seed " << seed;
    EXPECT_EQ(telegrams.back().ranges_m, good_ranges) << "seed " << seed;
    EXPECT_GT(decoded.drop(DropReason::kBadCrc) + decoded.drop(DropReason::kTruncated) +
                  decoded.drop(DropReason::kBadLength),
              0u)
        << "seed " << seed;
  }
}

}  // namespace
}  // namespace blockmap::hal::protocol::sick_lms2xx
