// SICK CoLa codec: real CoLa B telegrams against their reference decode, the five real TCP
// captures, the start-up command frames of a real log re-encoded byte for byte, encode/decode
// round trips in both dialects, chunking invariance and corruption (docs/protocols.md section 3).
#include "blockmap/hal/protocol/sick_cola.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "blockmap/core/arena.hpp"
#include "byte_streams.hpp"
#include "test_data.hpp"
#include "throwing_check.hpp"

namespace blockmap::hal::protocol::sick_cola {
namespace {

using blockmap::testing::bytes_of;
using blockmap::testing::Chunking;
using blockmap::testing::concat;
using Bytes = std::vector<std::uint8_t>;

constexpr double kPi = std::numbers::pi;
constexpr double kRadPerDeg = kPi / 180.0;

// --- decoding helpers

struct DecodedTelegram {
  Dialect dialect = Dialect::kColaB;
  std::string type;
  std::string command;
  Bytes payload;
  std::uint64_t start_offset = 0;
  TimestampNs stamp_ns = 0;
  int scan_index = -1;  // into Decoded::scans
};

struct Decoded {
  std::vector<DecodedTelegram> telegrams;
  std::vector<msg::LaserScan> scans;
  std::vector<ScanInfo> infos;
  std::vector<DropReason> rejections;
  std::vector<std::uint64_t> rejection_offsets;
  std::array<std::uint64_t, static_cast<std::size_t>(DropReason::kCount)> drops{};
  std::uint64_t dropped_bytes = 0;
  std::size_t buffered_after_flush = 0;
  Framing framing = Framing::kDetect;

  [[nodiscard]] std::uint64_t drop(DropReason reason) const {
    return drops[static_cast<std::size_t>(reason)];
  }
};

void record(const Decoder::Step& step, Decoded& out) {
  if (step.telegram != nullptr) {
    const Telegram& t = *step.telegram;
    DecodedTelegram copy{t.dialect,
                         std::string(t.type),
                         std::string(t.command),
                         Bytes(t.payload.begin(), t.payload.end()),
                         t.start_offset,
                         t.stamp_ns};
    if (step.scan != nullptr) {
      copy.scan_index = static_cast<int>(out.scans.size());
      out.scans.push_back(*step.scan);
      out.infos.push_back(*step.scan_info);
    }
    out.telegrams.push_back(std::move(copy));
  }
  if (step.rejected) {
    out.rejections.push_back(step.reason);
    out.rejection_offsets.push_back(step.start_offset);
  }
}

// Feeds `bytes` in the given chunking (chunk k stamped k * 1000), then flushes.
Decoded decode(std::span<const std::uint8_t> bytes, Chunking chunking = Chunking::kWhole,
               std::uint32_t seed = 1, const Config& config = {}) {
  auto decoder = std::make_unique<StaticDecoder<>>(config);
  Decoded out;
  TimestampNs stamp_ns = 0;
  blockmap::testing::feed_in_chunks(bytes, chunking, seed,
                                    [&](std::span<const std::uint8_t> chunk) {
                                      stamp_ns += 1000;
                                      for (;;) {
                                        const Decoder::Step step = decoder->push(chunk, stamp_ns);
                                        chunk = chunk.subspan(step.consumed);
                                        record(step, out);
                                        if (chunk.empty() && !step.has_event()) break;
                                      }
                                    });
  for (;;) {
    const Decoder::Step step = decoder->flush();
    record(step, out);
    if (!step.has_event()) break;
  }
  for (std::size_t r = 0; r < out.drops.size(); ++r) {
    out.drops[r] = decoder->drops().value(static_cast<DropReason>(r));
  }
  EXPECT_EQ(decoder->drops().total(), [&] {
    std::uint64_t sum = 0;
    for (std::uint64_t d : out.drops) sum += d;
    return sum;
  }());
  out.dropped_bytes = decoder->dropped_bytes();
  out.buffered_after_flush = decoder->buffered_bytes();
  out.framing = decoder->framing();
  return out;
}

std::uint64_t fnv(const void* data, std::size_t size, std::uint64_t hash = 1469598103934665603ULL) {
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    hash = (hash ^ bytes[i]) * 1099511628211ULL;
  }
  return hash;
}

// Everything a decoded scan says except its receive stamp, for exact comparisons.
std::string scan_summary(const msg::LaserScan& s) {
  std::ostringstream out;
  out.precision(17);
  const std::size_t n = s.beam_count;
  out << "n" << n << " a" << s.start_angle_rad << '+' << s.angle_increment_rad << " t"
      << s.scan_period_s << '/' << s.time_increment_s << " c" << s.scan_counter << " i"
      << s.has_intensities << " r" << fnv(s.ranges_m.data(), n * sizeof(float)) << " q"
      << fnv(s.intensities.data(), n * sizeof(float)) << " s"
      << fnv(s.status.data(), n * sizeof(msg::BeamStatus));
  return out.str();
}

std::vector<std::string> summaries(const Decoded& decoded) {
  std::vector<std::string> lines;
  for (const DecodedTelegram& t : decoded.telegrams) {
    std::string line = std::string(to_string(t.dialect)) + ' ' + t.type + ' ' + t.command + " @" +
                       std::to_string(t.start_offset) + " p" +
                       std::to_string(fnv(t.payload.data(), t.payload.size()));
    if (t.scan_index >= 0) {
      line += ' ' + scan_summary(decoded.scans[static_cast<std::size_t>(t.scan_index)]);
    }
    lines.push_back(line);
  }
  return lines;
}

Bytes read_project(std::string_view relative) {
  return blockmap::testing::read_bytes(blockmap::testing::project_data(relative));
}

Bytes all16() {
  return read_project("cola/sick_scan_xd_test_pcapng_all16_frames.bin");
}

std::span<const std::uint8_t> frame(const Bytes& frames, std::size_t index) {
  return std::span<const std::uint8_t>(frames).subspan(index * 3374, 3374);
}

// One of the log's command frames, as bytes: "02 02 02 02 00 00 00 07 73 4D 4E 20 52 75 6E 19".
Bytes hex_bytes(const std::string& text) {
  Bytes bytes;
  std::istringstream in(text);
  std::string token;
  while (in >> token) {
    bytes.push_back(static_cast<std::uint8_t>(std::stoul(token, nullptr, 16)));
  }
  return bytes;
}

// A line of the start-up log's table: 'sMN Command <payload>'  len=N  xor=HH  <frame bytes>.
struct LoggedCommand {
  std::string type;     // sMN, sWN, sRN, sEN
  std::string command;  // SetAccessMode, Run, ...
  unsigned long length = 0;
  unsigned long checksum = 0;
  std::string frame_hex;
};

std::optional<LoggedCommand> parse_logged_command(const std::string& line) {
  if (line.size() < 6 || line[0] != '\'' || line[1] != 's' || line[4] != ' ') {
    return std::nullopt;
  }
  LoggedCommand logged;
  logged.type = line.substr(1, 3);
  const std::size_t name_end = line.find_first_of(" '", 5);
  logged.command = line.substr(5, name_end - 5);
  const std::size_t len_at = line.rfind("len=");
  const std::size_t xor_at = line.rfind("xor=");
  if (logged.command.empty() || len_at == std::string::npos || xor_at == std::string::npos ||
      xor_at < len_at) {
    return std::nullopt;
  }
  std::istringstream fields(line.substr(len_at + 4, xor_at - len_at - 4));
  fields >> logged.length;
  logged.checksum = std::stoul(line.substr(xor_at + 4, 2), nullptr, 16);
  logged.frame_hex = line.substr(xor_at + 6);
  return logged;
}

template <typename Encode>
Bytes encoded(Encode&& encode, std::size_t capacity = std::size_t{32} * 1024) {
  Bytes out(capacity);
  const std::size_t length = encode(std::span<std::uint8_t>(out));
  EXPECT_GT(length, 0u);
  out.resize(length);
  return out;
}

// --- golden frames (docs/protocols.md 3.2 worked examples)

TEST(SickCola, ChecksumAndFramingWorkedExamples) {
  const Bytes run = bytes_of("sMN Run");
  EXPECT_EQ(checksum(run), 0x19);
  EXPECT_EQ(encoded([](auto out) { return encode_run(Dialect::kColaB, out); }),
            hex_bytes("02 02 02 02 00 00 00 07 73 4D 4E 20 52 75 6E 19"));
  EXPECT_EQ(encoded([](auto out) { return encode_scan_events(Dialect::kColaB, true, out); }),
            hex_bytes("02 02 02 02 00 00 00 11 73 45 4E 20 4C 4D 44 73 63 61 6E 64 61 74 61 20 "
                      "01 33"));
  Bytes framed(64);
  framed.resize(frame_cola_b(run, framed));
  EXPECT_EQ(framed, hex_bytes("02 02 02 02 00 00 00 07 73 4D 4E 20 52 75 6E 19"));
  Bytes small(15);
  EXPECT_EQ(frame_cola_b(run, small), 0u) << "one byte short of the frame";
}

TEST(SickCola, ColaACommandsAreTextBetweenStxAndEtx) {
  const auto text = [](const Bytes& frame) {
    EXPECT_EQ(frame.front(), 0x02);
    EXPECT_EQ(frame.back(), 0x03);
    return std::string(frame.begin() + 1, frame.end() - 1);
  };
  // The CoLa A commands of the public drivers (docs/protocols.md 3.3; S14 sends "3 F4724744").
  EXPECT_EQ(text(encoded([](auto out) {
              return encode_set_access_mode(Dialect::kColaA, kAccessLevelAuthorizedClient,
                                            kAuthorizedClientPasswordHash, out);
            })),
            "sMN SetAccessMode 3 F4724744");
  EXPECT_EQ(text(encoded([](auto out) { return encode_scan_events(Dialect::kColaA, false, out); })),
            "sEN LMDscandata 0");
  EXPECT_EQ(text(encoded([](auto out) { return encode_scan_poll(Dialect::kColaA, out); })),
            "sRN LMDscandata");
  EXPECT_EQ(text(encoded([](auto out) { return encode_start_measurement(Dialect::kColaA, out); })),
            "sMN LMCstartmeas");
  // S15's LMS1xx driver writes the same 12 fields as "%02X 00 %d %d 0 %02X 00 %d %d 0 %d +%d".
  ScanDataConfig config;
  config.rssi = false;
  config.rssi_16bit = true;
  config.time = false;
  EXPECT_EQ(text(encoded(
                [&](auto out) { return encode_scan_data_config(Dialect::kColaA, config, out); })),
            "sWN LMDscandatacfg 1 0 0 1 0 0 0 0 0 0 0 +1");
  Bytes framed(32);
  framed.resize(frame_cola_a("sMN Run", framed));
  EXPECT_EQ(text(framed), "sMN Run");
}

TEST(SickCola, StartUpLogCommandFramesReEncodeByteForByte) {
  std::istringstream file(blockmap::testing::read_text(
      blockmap::testing::project_data("cola/colab_command_frames_from_tim5xx_startup_log.txt")));
  ScanDataConfig tim_config;  // as logged: RSSI on, 8-bit, time block on
  tim_config.rssi = true;
  tim_config.rssi_16bit = false;
  tim_config.time = true;
  std::size_t checked = 0;
  std::string line;
  while (std::getline(file, line)) {
    const std::optional<LoggedCommand> row = parse_logged_command(line);
    if (!row) {
      continue;
    }
    const Bytes logged = hex_bytes(row->frame_hex);
    ASSERT_EQ(logged.size(), row->length + 9) << line;
    EXPECT_EQ(logged.back(), row->checksum) << line;
    const std::string& type = row->type;
    const std::string& command = row->command;
    Bytes ours;
    if (command == "SetAccessMode") {
      ours = encoded([](auto out) {
        return encode_set_access_mode(Dialect::kColaB, kAccessLevelAuthorizedClient,
                                      kAuthorizedClientPasswordHash, out);
      });
    } else if (command == "EIHstCola") {
      ours = encoded([](auto out) {
        return TelegramWriter(Dialect::kColaB, out, "sWN", "EIHstCola").u8(1).finish();
      });
    } else if (command == "LMDscandatacfg") {
      ours = encoded(
          [&](auto out) { return encode_scan_data_config(Dialect::kColaB, tim_config, out); });
    } else if (command == "LMCstartmeas") {
      ours = encoded([](auto out) { return encode_start_measurement(Dialect::kColaB, out); });
    } else if (command == "Run") {
      ours = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
    } else if (type == "sEN") {
      ours = encoded([](auto out) { return encode_scan_events(Dialect::kColaB, true, out); });
    } else {
      ours = encoded([&](auto out) { return encode_command(Dialect::kColaB, type, command, out); });
    }
    EXPECT_EQ(ours, logged) << line;
    // And each decodes back to its type and command.
    const Decoded decoded = decode(logged);
    ASSERT_EQ(decoded.telegrams.size(), 1u) << line;
    EXPECT_EQ(decoded.telegrams[0].type, type);
    EXPECT_EQ(decoded.telegrams[0].command, command);
    ++checked;
  }
  EXPECT_EQ(checked, 9u);
}

// --- the 16 real frames of sick_scan_xd's test.pcapng

TEST(SickCola, SixteenRealFramesDecodeWithEveryChecksumAccepted) {
  const Bytes bytes = all16();
  ASSERT_EQ(bytes.size(), 16u * 3374u);
  const Decoded decoded = decode(bytes);
  ASSERT_EQ(decoded.telegrams.size(), 16u);
  ASSERT_EQ(decoded.scans.size(), 16u);
  EXPECT_TRUE(decoded.rejections.empty());
  EXPECT_EQ(decoded.dropped_bytes, 0u);
  EXPECT_EQ(decoded.framing, Framing::kColaB);
  for (std::size_t i = 0; i < 16; ++i) {
    const DecodedTelegram& t = decoded.telegrams[i];
    EXPECT_EQ(t.type, "sSN");
    EXPECT_EQ(t.command, "LMDscandata");
    EXPECT_EQ(t.start_offset, i * 3374u);
    EXPECT_EQ(decoded.scans[i].beam_count, 811);
    EXPECT_TRUE(decoded.scans[i].has_intensities);
    // The device's scan counter advances by one per telegram in this capture.
    EXPECT_EQ(std::size_t{decoded.infos[i].scan_counter}, decoded.infos[0].scan_counter + i);
  }
}

TEST(SickCola, Frame00MatchesTheReferenceDecodeFieldByField) {
  const nlohmann::json ref = nlohmann::json::parse(blockmap::testing::read_text(
      blockmap::testing::project_data("cola/sick_scan_xd_test_pcapng_frame00.decoded.json")));
  const Bytes bytes = all16();
  const Decoded decoded = decode(frame(bytes, 0));
  ASSERT_EQ(decoded.scans.size(), 1u);
  const ScanInfo& info = decoded.infos[0];
  const msg::LaserScan& scan = decoded.scans[0];
  EXPECT_EQ(decoded.telegrams[0].payload.size() + 16u + 9u, ref["total_bytes"].get<std::size_t>());
  EXPECT_EQ(info.version, ref["version"].get<int>());
  EXPECT_EQ(info.device_number, ref["device_number"].get<int>());
  EXPECT_EQ(info.serial_number, ref["serial_number"].get<std::uint32_t>());
  EXPECT_EQ(info.telegram_counter, ref["telegram_counter"].get<int>());
  EXPECT_EQ(info.scan_counter, ref["scan_counter"].get<int>());
  EXPECT_EQ(info.time_since_startup_us, ref["time_since_startup_us"].get<std::uint32_t>());
  EXPECT_EQ(info.time_of_transmission_us, ref["time_of_transmission_us"].get<std::uint32_t>());
  EXPECT_EQ(info.digital_outputs[0], 0x08);  // "digital_outputs": "08 00"
  EXPECT_EQ(ref["digital_outputs"].get<std::string>(), "08 00");
  EXPECT_EQ(info.scan_frequency_centihz, ref["scan_frequency_x100_hz"].get<std::uint32_t>());
  EXPECT_EQ(info.measurement_frequency_hectohz,
            ref["measurement_frequency_div100_hz"].get<std::uint32_t>());
  EXPECT_EQ(info.encoder_count, ref["num_encoders"].get<int>());
  EXPECT_EQ(info.channel8_count, ref["channels8_count"].get<int>());

  const nlohmann::json& dist = ref["channels16"][0];
  const nlohmann::json& rssi = ref["channels16"][1];
  ASSERT_EQ(std::size_t{info.channel16_count}, ref["channels16"].size());
  EXPECT_STREQ(info.distance.name.data(), dist["name"].get<std::string>().c_str());
  EXPECT_STREQ(info.rssi.name.data(), rssi["name"].get<std::string>().c_str());
  EXPECT_EQ(info.distance.scale_factor, dist["scale_factor"].get<float>());
  EXPECT_EQ(info.distance.scale_offset, dist["scale_offset"].get<float>());
  EXPECT_EQ(info.distance.start_angle_1e4deg, dist["start_angle_1e4deg"].get<std::int32_t>());
  EXPECT_EQ(info.distance.step_1e4deg, dist["step_1e4deg"].get<int>());
  EXPECT_EQ(info.distance.count, dist["count"].get<int>());
  EXPECT_EQ(info.distance.bits, 16);
  EXPECT_EQ(info.rssi.bits, 16);

  // The LaserScan: SICK -45 deg is -135 deg in the scanner frame; 1/10000 degree steps.
  ASSERT_EQ(scan.beam_count, dist["count"].get<int>());
  EXPECT_NEAR(scan.start_angle_rad,
              (dist["start_angle_1e4deg"].get<double>() / 1e4 - 90.0) * kRadPerDeg, 1e-12);
  EXPECT_NEAR(scan.start_angle_rad, -135.0 * kRadPerDeg, 1e-12);
  EXPECT_NEAR(scan.angle_increment_rad, 0.3333 * kRadPerDeg, 1e-15);
  EXPECT_NEAR(scan.scan_period_s, 1.0 / 15.0, 1e-15);
  EXPECT_NEAR(scan.time_increment_s, 1.0 / 16200.0, 1e-15);
  EXPECT_EQ(scan.scan_counter, ref["scan_counter"].get<std::uint32_t>());
  EXPECT_TRUE(scan.has_intensities);
  const auto& ranges = dist["values"];
  const auto& intensities = rssi["values"];
  std::size_t no_return = 0;
  for (std::size_t i = 0; i < scan.beam_count; ++i) {
    const auto raw = ranges[i].get<std::uint32_t>();
    const auto raw_rssi = intensities[i].get<std::uint32_t>();
    EXPECT_FLOAT_EQ(scan.ranges_m[i], static_cast<float>(raw * 0.001)) << i;
    EXPECT_EQ(scan.intensities[i], static_cast<float>(raw_rssi)) << i;
    const bool expect_no_return = raw == 0 || raw_rssi == 0;
    EXPECT_EQ(scan.status[i],
              expect_no_return ? msg::BeamStatus::kNoReturn : msg::BeamStatus::kValid)
        << i;
    no_return += expect_no_return ? 1U : 0U;
  }
  EXPECT_GT(no_return, 10u) << "the frame has a run of value 2 with RSSI 0 (docs/protocols.md 3.5)";
  EXPECT_FLOAT_EQ(scan.ranges_m[0], 0.626F);
  EXPECT_FLOAT_EQ(scan.ranges_m[810], 0.176F);

  ASSERT_TRUE(info.has_device_time);
  EXPECT_EQ(info.device_time.year, ref["time"]["year"].get<int>());
  EXPECT_EQ(info.device_time.month, ref["time"]["month"].get<int>());
  EXPECT_EQ(info.device_time.day, ref["time"]["day"].get<int>());
  EXPECT_EQ(info.device_time.hour, ref["time"]["hour"].get<int>());
  EXPECT_EQ(info.device_time.minute, ref["time"]["minute"].get<int>());
  EXPECT_EQ(info.device_time.second, ref["time"]["second"].get<int>());
  EXPECT_EQ(info.device_time.microsecond, ref["time"]["usec"].get<std::uint32_t>());
}

TEST(SickCola, RssiZeroRuleCanBeSwitchedOff) {
  Config config;
  config.rssi_zero_is_no_return = false;
  const Bytes bytes = all16();
  const Decoded decoded = decode(frame(bytes, 0), Chunking::kWhole, 1, config);
  ASSERT_EQ(decoded.scans.size(), 1u);
  const msg::LaserScan& scan = decoded.scans[0];
  EXPECT_EQ(scan.intensities[3], 0.0F);
  EXPECT_FLOAT_EQ(scan.ranges_m[3], 0.002F);
  EXPECT_EQ(scan.status[3], msg::BeamStatus::kValid);
}

TEST(SickCola, RangeMinimumMarksTooCloseBeams) {
  Config config;
  config.range_min_m = 0.5;
  config.range_max_m = 25.0;
  const Bytes bytes = all16();
  const Decoded decoded = decode(frame(bytes, 0), Chunking::kWhole, 1, config);
  ASSERT_EQ(decoded.scans.size(), 1u);
  const msg::LaserScan& scan = decoded.scans[0];
  EXPECT_EQ(scan.range_min_m, 0.5);
  EXPECT_EQ(scan.range_max_m, 25.0);
  std::size_t too_close = 0;
  for (std::size_t i = 0; i < scan.beam_count; ++i) {
    if (scan.status[i] == msg::BeamStatus::kValid) {
      EXPECT_GE(scan.ranges_m[i], 0.5F) << i;
    }
    too_close += scan.status[i] == msg::BeamStatus::kTooClose ? 1U : 0U;
  }
  EXPECT_GT(too_close, 0u) << "frame 00 has returns at 0.15..0.3 m";
}

// The same telegram in CoLa A, written here from the reference decode with printf (not with the
// codec's writer): tokens in upper-case hex, floats as IEEE bits, negative s32 as two's complement.
std::string cola_a_frame00_text(const nlohmann::json& ref) {
  std::string text = "sSN LMDscandata";
  const auto token = [&text](std::uint32_t value) {
    char buffer[16];
    std::snprintf(buffer, sizeof buffer, " %X", value);
    text += buffer;
  };
  token(ref["version"].get<std::uint32_t>());
  token(ref["device_number"].get<std::uint32_t>());
  token(ref["serial_number"].get<std::uint32_t>());
  text += " 0 0";
  token(ref["telegram_counter"].get<std::uint32_t>());
  token(ref["scan_counter"].get<std::uint32_t>());
  token(ref["time_since_startup_us"].get<std::uint32_t>());
  token(ref["time_of_transmission_us"].get<std::uint32_t>());
  text += " 0 0 8 0 0";  // inputs, outputs "08 00", reserved
  token(ref["scan_frequency_x100_hz"].get<std::uint32_t>());
  token(ref["measurement_frequency_div100_hz"].get<std::uint32_t>());
  text += " 0 2";  // encoders, 16-bit channels
  for (const auto& channel : ref["channels16"]) {
    text += ' ';  // appended piecewise: gcc 12's -Wrestrict misfires on "literal" + string
    text += channel["name"].get<std::string>();
    text += " 3F800000 00000000";
    token(static_cast<std::uint32_t>(channel["start_angle_1e4deg"].get<std::int32_t>()));
    token(channel["step_1e4deg"].get<std::uint32_t>());
    token(channel["count"].get<std::uint32_t>());
    for (const auto& value : channel["values"]) token(value.get<std::uint32_t>());
  }
  text += " 0 0 0 0 1 7B2 1 1 0 32 E 21340 0";  // 8-bit channels, blocks, time, events
  return text;
}

TEST(SickCola, ColaAScanDecodesLikeItsColaBOriginal) {
  const nlohmann::json ref = nlohmann::json::parse(blockmap::testing::read_text(
      blockmap::testing::project_data("cola/sick_scan_xd_test_pcapng_frame00.decoded.json")));
  const std::string text = cola_a_frame00_text(ref);
  EXPECT_NE(text.find(" FFF92230 D05 32B 272 291 268 2 "), std::string::npos) << "-450000";
  const Bytes cola_a = concat({bytes_of("\x02"), bytes_of(text), bytes_of("\x03")});
  const Bytes bytes = all16();
  const Decoded from_a = decode(cola_a);
  const Decoded from_b = decode(frame(bytes, 0));
  ASSERT_EQ(from_a.scans.size(), 1u);
  ASSERT_EQ(from_b.scans.size(), 1u);
  EXPECT_EQ(from_a.telegrams[0].dialect, Dialect::kColaA);
  EXPECT_EQ(from_a.framing, Framing::kColaA);
  EXPECT_EQ(scan_summary(from_a.scans[0]), scan_summary(from_b.scans[0]));
  EXPECT_EQ(from_a.infos[0].serial_number, from_b.infos[0].serial_number);
  EXPECT_EQ(from_a.infos[0].time_of_transmission_us, from_b.infos[0].time_of_transmission_us);
  EXPECT_EQ(from_a.infos[0].distance.start_angle_1e4deg, -450000);
  EXPECT_TRUE(from_a.infos[0].has_device_time);
  EXPECT_EQ(from_a.infos[0].device_time.microsecond, 136000u);
}

TEST(SickCola, ColaAScanWithDeviceNameBlockAndEightBitRssi) {
  // An LMS1xx-style telegram: one encoder, RSSI1 as an 8-bit channel, then the device name
  // block "1 B not defined" (a length-prefixed string with a space in it).
  const std::string text =
      "\x02sRA LMDscandata 1 1 109F5FA 0 0 B5A0 A6D9 69FAC4A1 69FB7AD1 0 0 7 0 0 9C4 168 1 0 3E8 "
      "1 DIST1 3F800000 00000000 6DDD0 9C4 3 1B8 0 1B9 1 RSSI1 3F800000 00000000 6DDD0 9C4 3 "
      "C9 0 7F 0 1 B not defined 0 0 0\x03";
  const Decoded decoded = decode(bytes_of(text));
  ASSERT_EQ(decoded.scans.size(), 1u);
  EXPECT_TRUE(decoded.rejections.empty());
  const msg::LaserScan& scan = decoded.scans[0];
  const ScanInfo& info = decoded.infos[0];
  EXPECT_EQ(decoded.telegrams[0].type, "sRA");
  EXPECT_EQ(info.serial_number, 0x109F5FAu);
  EXPECT_EQ(info.encoder_count, 1);
  EXPECT_EQ(info.encoder_speed, 0x3E8);
  EXPECT_EQ(info.rssi.bits, 8);
  EXPECT_FALSE(info.has_device_time);
  EXPECT_EQ(scan.beam_count, 3);
  EXPECT_NEAR(scan.start_angle_rad, (45.0 - 90.0) * kRadPerDeg, 1e-12);  // 0x6DDD0 = 450000
  EXPECT_NEAR(scan.angle_increment_rad, 0.25 * kRadPerDeg, 1e-15);       // 0x9C4 = 2500
  EXPECT_NEAR(scan.scan_period_s, 1.0 / 25.0, 1e-15);                    // 0x9C4 = 2500
  EXPECT_FLOAT_EQ(scan.ranges_m[0], 0.44F);
  EXPECT_EQ(scan.status[1], msg::BeamStatus::kNoReturn);
  EXPECT_EQ(scan.intensities[2], 127.0F);
}

// --- the five real TCP captures (../shared, Apache-2.0; PROVENANCE.txt, verification_output.txt)

// The TCP payloads of a capture, in order ("tcp.payload": "02:02:02:02:00:..."); read once.
const Bytes& pcapng_json_stream(const std::filesystem::path& path) {
  static std::map<std::filesystem::path, Bytes> cache;
  if (const auto found = cache.find(path); found != cache.end()) {
    return found->second;
  }
  // Each entry has exactly one "tcp.payload" (pcap_json_converter's fixed layout): a text search
  // finds them in order, much faster than a JSON parse in sanitized and emulated builds.
  const std::string text = blockmap::testing::read_text(path);
  const std::string_view key = R"("tcp.payload": ")";
  const auto nibble = [](char c) { return c <= '9' ? c - '0' : (c | 0x20) - 'a' + 10; };
  Bytes stream;
  for (std::size_t at = text.find(key); at != std::string::npos; at = text.find(key, at)) {
    at += key.size();
    for (; at + 1 < text.size() && text[at] != '"'; at += text[at + 2] == ':' ? 3U : 2U) {
      stream.push_back(static_cast<std::uint8_t>(nibble(text[at]) * 16 + nibble(text[at + 1])));
    }
  }
  return cache.emplace(path, std::move(stream)).first->second;
}

struct CaptureFacts {
  const char* file;
  std::size_t telegrams;
  std::size_t scans;
  std::uint16_t beams;
  double start_deg;  // SICK's
  double step_deg;
  double scan_hz;
  std::uint8_t rssi_bits;  // 0: no RSSI channel
  std::uint16_t first_counter;
  std::uint16_t last_counter;
};

// From verification_output.txt and PROVENANCE.txt (an independent throwaway parser).
constexpr CaptureFacts kCaptures[] = {
    {"20210113_tim871s_elephant.pcapng.json", 278, 150, 811, -45.0, 0.3333, 15.0, 16, 60532, 60681},
    {"20210125-tim781s-scandata.pcapng.json", 277, 140, 811, -45.0, 0.3333, 15.0, 16, 39236, 39375},
    {"20210301_lms511.pcapng.json", 277, 136, 1141, -5.0, 0.1667, 25.0, 8, 10335, 10470},
    {"20210302_lms111.pcapng.json", 277, 175, 541, -45.0, 0.5, 50.0, 0, 4, 175},
    {"20210302_lms511.pcapng.json", 277, 174, 1141, -5.0, 0.1667, 25.0, 8, 54484, 54657},
};

TEST(SickCola, RealCapturesDecodeEveryTelegramWithEveryChecksumAccepted) {
  for (const CaptureFacts& facts : kCaptures) {
    SCOPED_TRACE(facts.file);
    BLOCKMAP_SHARED_DATA_OR_SKIP(path, std::string("real/sick-cola-captures/") + facts.file);
    const Bytes& stream = pcapng_json_stream(path);
    const Decoded decoded = decode(stream);
    EXPECT_EQ(decoded.telegrams.size(), facts.telegrams);
    EXPECT_TRUE(decoded.rejections.empty());
    EXPECT_EQ(decoded.dropped_bytes, 0u);
    EXPECT_EQ(decoded.buffered_after_flush, 0u);
    ASSERT_EQ(decoded.scans.size(), facts.scans);
    for (std::size_t i = 0; i < decoded.scans.size(); ++i) {
      const msg::LaserScan& scan = decoded.scans[i];
      const ScanInfo& info = decoded.infos[i];
      ASSERT_EQ(scan.beam_count, facts.beams) << i;
      EXPECT_NEAR(scan.start_angle_rad, (facts.start_deg - 90.0) * kRadPerDeg, 1e-12);
      EXPECT_NEAR(scan.angle_increment_rad, facts.step_deg * kRadPerDeg, 1e-12);
      EXPECT_NEAR(scan.scan_period_s, 1.0 / facts.scan_hz, 1e-12);
      EXPECT_GT(scan.time_increment_s, 0.0);
      EXPECT_EQ(scan.has_intensities, facts.rssi_bits != 0);
      if (facts.rssi_bits != 0) {
        EXPECT_EQ(info.rssi.bits, facts.rssi_bits);
      }
      EXPECT_EQ(info.distance.scale_factor, 1.0F);
      EXPECT_TRUE(info.has_device_time);
    }
    EXPECT_EQ(decoded.infos.front().scan_counter, facts.first_counter);
    EXPECT_EQ(decoded.infos.back().scan_counter, facts.last_counter);
    // The host's start-up telegrams are in the stream too: SetAccessMode and its answer.
    EXPECT_EQ(decoded.telegrams[0].type, "sMN");
    EXPECT_EQ(decoded.telegrams[0].command, "SetAccessMode");
    EXPECT_EQ(decoded.telegrams[1].type, "sAN");
    EXPECT_EQ(decoded.telegrams[1].payload, Bytes{1});
  }
}

TEST(SickCola, RealCapturesHostConfigurationReEncodesByteForByte) {
  // Each capture's sWN LMDscandatacfg, rebuilt from what its scans show (RSSI channel and width).
  for (const CaptureFacts& facts : kCaptures) {
    SCOPED_TRACE(facts.file);
    BLOCKMAP_SHARED_DATA_OR_SKIP(path, std::string("real/sick-cola-captures/") + facts.file);
    const Bytes& stream = pcapng_json_stream(path);
    const Decoded decoded = decode(stream);
    ScanDataConfig config;
    config.rssi = facts.rssi_bits != 0;
    config.rssi_16bit = facts.rssi_bits == 16;
    config.time = true;
    const Bytes ours =
        encoded([&](auto out) { return encode_scan_data_config(Dialect::kColaB, config, out); });
    std::size_t matched = 0;
    for (const DecodedTelegram& t : decoded.telegrams) {
      if (t.type == "sWN" && t.command == "LMDscandatacfg") {
        const Bytes theirs(
            stream.begin() + static_cast<std::ptrdiff_t>(t.start_offset),
            stream.begin() + static_cast<std::ptrdiff_t>(t.start_offset + ours.size()));
        EXPECT_EQ(ours, theirs);
        ++matched;
      }
    }
    EXPECT_EQ(matched, 1u);
  }
}

TEST(SickCola, ErrorRepliesWithoutCommandNameAreTelegrams) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(path, "real/sick-cola-captures/20210301_lms511.pcapng.json");
  const Decoded decoded = decode(pcapng_json_stream(path));
  std::size_t errors = 0;
  for (const DecodedTelegram& t : decoded.telegrams) {
    if (t.type == "sFA") {
      EXPECT_TRUE(t.command.empty());
      EXPECT_EQ(t.payload, (Bytes{0x00, 0x03}));
      ++errors;
    }
  }
  EXPECT_EQ(errors, 18u) << "verification_output.txt counts 18 'sFA\\x00\\x03'";
}

// --- encode -> decode round trips

msg::LaserScan synthetic_scan(std::uint16_t beams, bool intensities) {
  msg::LaserScan scan;
  scan.start_angle_rad = -135.0 * kRadPerDeg;
  scan.angle_increment_rad = 0.3333 * kRadPerDeg;
  scan.scan_period_s = 1.0 / 15.0;
  scan.time_increment_s = 1.0 / 16200.0;
  scan.scan_counter = 4711;
  scan.beam_count = beams;
  scan.has_intensities = intensities;
  for (std::size_t i = 0; i < beams; ++i) {
    const bool hit = i % 7 != 3;
    scan.ranges_m[i] =
        hit ? static_cast<float>(static_cast<double>(100 + (i * 37) % 20000) * 0.001) : 0.0F;
    scan.status[i] = hit ? msg::BeamStatus::kValid : msg::BeamStatus::kNoReturn;
    scan.intensities[i] = intensities && hit ? static_cast<float>(1 + (i * 13) % 250) : 0.0F;
  }
  return scan;
}

void expect_same_scan(const msg::LaserScan& decoded, const msg::LaserScan& original) {
  ASSERT_EQ(decoded.beam_count, original.beam_count);
  EXPECT_NEAR(decoded.start_angle_rad, original.start_angle_rad, 1e-12);
  EXPECT_NEAR(decoded.angle_increment_rad, original.angle_increment_rad, 1e-12);
  EXPECT_NEAR(decoded.scan_period_s, original.scan_period_s, 1e-15);
  EXPECT_NEAR(decoded.time_increment_s, original.time_increment_s, 1e-15);
  EXPECT_EQ(decoded.scan_counter, original.scan_counter);
  EXPECT_EQ(decoded.has_intensities, original.has_intensities);
  for (std::size_t i = 0; i < original.beam_count; ++i) {
    EXPECT_FLOAT_EQ(decoded.ranges_m[i], original.ranges_m[i]) << i;
    EXPECT_EQ(decoded.status[i], original.status[i]) << i;
    EXPECT_EQ(decoded.intensities[i], original.intensities[i]) << i;
  }
}

TEST(SickCola, EncodedScansDecodeBackInBothDialects) {
  for (const Dialect dialect : {Dialect::kColaB, Dialect::kColaA}) {
    for (const bool rssi16 : {true, false}) {
      for (const bool intensities : {true, false}) {
        SCOPED_TRACE(std::string(to_string(dialect)) + (rssi16 ? " rssi16" : " rssi8") +
                     (intensities ? "" : " no-rssi"));
        const msg::LaserScan original = synthetic_scan(811, intensities);
        ScanTelegramFields fields;
        fields.rssi_16bit = rssi16;
        fields.serial_number = 0x01199506;
        fields.telegram_counter = 77;
        fields.has_device_time = true;
        fields.device_time = DeviceTime{2026, 11, 22, 3, 4, 5, 678901};
        const Bytes bytes =
            encoded([&](auto out) { return encode_scan(dialect, original, fields, out); });
        const Decoded decoded = decode(bytes);
        ASSERT_EQ(decoded.scans.size(), 1u);
        EXPECT_TRUE(decoded.rejections.empty());
        EXPECT_EQ(decoded.telegrams[0].dialect, dialect);
        EXPECT_EQ(decoded.telegrams[0].type, "sSN");
        expect_same_scan(decoded.scans[0], original);
        const ScanInfo& info = decoded.infos[0];
        EXPECT_EQ(info.serial_number, fields.serial_number);
        EXPECT_EQ(info.telegram_counter, fields.telegram_counter);
        EXPECT_EQ(info.scan_frequency_centihz, 1500u);
        EXPECT_EQ(info.measurement_frequency_hectohz, 162u);
        EXPECT_EQ(info.distance.start_angle_1e4deg, -450000);
        EXPECT_EQ(info.distance.step_1e4deg, 3333);
        if (intensities) {
          EXPECT_EQ(info.rssi.bits, rssi16 ? 16 : 8);
        }
        ASSERT_TRUE(info.has_device_time);
        EXPECT_EQ(info.device_time.year, 2026);
        EXPECT_EQ(info.device_time.microsecond, 678901u);
      }
    }
  }
}

TEST(SickCola, EncodingAPolledMaximumScanFitsTheDefaultBuffer) {
  // An LMS511 at 1/6 degree with 16-bit RSSI, in the bulkier dialect.
  msg::LaserScan original = synthetic_scan(msg::kMaxLaserBeams, true);
  original.start_angle_rad = -95.0 * kRadPerDeg;
  original.angle_increment_rad = 0.1667 * kRadPerDeg;
  ScanTelegramFields fields;
  fields.type = "sRA";
  const Bytes bytes =
      encoded([&](auto out) { return encode_scan(Dialect::kColaA, original, fields, out); });
  EXPECT_LE(bytes.size(), kDefaultTelegramCapacityBytes);
  const Decoded decoded = decode(bytes);
  ASSERT_EQ(decoded.scans.size(), 1u);
  EXPECT_EQ(decoded.telegrams[0].type, "sRA");
  expect_same_scan(decoded.scans[0], original);
  Bytes small(bytes.size() - 1);
  EXPECT_EQ(encode_scan(Dialect::kColaA, original, fields, small), 0u);
}

TEST(SickCola, DetectedFramingFollowsTheFirstTelegram) {
  const Bytes run_a = encoded([](auto out) { return encode_run(Dialect::kColaA, out); });
  const Bytes run_b = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
  EXPECT_EQ(decode(run_a).framing, Framing::kColaA);
  EXPECT_EQ(decode(run_b).framing, Framing::kColaB);
  // Once CoLa B is detected, a CoLa A telegram is noise; configured CoLa A reads it.
  const Decoded mixed = decode(concat({run_b, run_a}));
  EXPECT_EQ(mixed.telegrams.size(), 1u);
  EXPECT_EQ(mixed.drop(DropReason::kGarbage), run_a.size());
  Config cola_a;
  cola_a.framing = Framing::kColaA;
  const Decoded configured = decode(run_a, Chunking::kWhole, 1, cola_a);
  ASSERT_EQ(configured.telegrams.size(), 1u);
  EXPECT_EQ(configured.telegrams[0].command, "Run");
}

// --- chunking invariance and stamps

// A stream with every path of the decoder in it: scans, commands, garbage, a false start whose
// length hides real telegrams, a huge length, a cut-off telegram and a bad checksum.
Bytes eventful_stream() {
  const Bytes frames = all16();
  const Bytes run = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
  const Bytes poll = encoded([](auto out) { return encode_scan_poll(Dialect::kColaB, out); });
  Bytes bad_checksum = run;
  // Index arithmetic, not back(): gcc 12 at -O3 warns that back() of a possibly empty vector
  // reads index -1 (a false positive that -Werror turns into a failed build).
  EXPECT_FALSE(bad_checksum.empty());
  bad_checksum.at(bad_checksum.size() - 1) ^= 0x40;
  const Bytes false_start = hex_bytes("02 02 02 02 00 00 01 00");  // claims 256 bytes
  const Bytes huge = hex_bytes("02 02 02 02 7F FF FF FF");
  return concat({blockmap::testing::random_garbage(300, 5), frame(frames, 0), false_start, run,
                 poll, run, blockmap::testing::random_garbage(250, 6), frame(frames, 1), huge,
                 frame(frames, 2), frame(frames, 3).first(2000), frame(frames, 4), bad_checksum,
                 frame(frames, 5), bytes_of("\x02\x02garbage\x02"), frame(frames, 6)});
}

TEST(SickCola, ResultDoesNotDependOnChunking) {
  const Bytes plain = all16();
  const Bytes eventful = eventful_stream();
  const msg::LaserScan scan = synthetic_scan(300, true);
  const Bytes cola_a = concat(
      {encoded([&](auto out) { return encode_scan(Dialect::kColaA, scan, {}, out); }),
       bytes_of("\x02sAN Run 1\x03"), bytes_of("\x02sRA LMDsc"),
       bytes_of("\x02sAN SetAccessMode 1\x03"), bytes_of("noise\x02sWA LMD\x01scandatacfg\x03"),
       encoded([&](auto out) { return encode_scan(Dialect::kColaA, scan, {}, out); })});
  for (const Bytes* stream : {&plain, &eventful, &cola_a}) {
    const Decoded whole = decode(*stream, Chunking::kWhole);
    ASSERT_FALSE(whole.telegrams.empty());
    const Decoded single = decode(*stream, Chunking::kByteByByte);
    EXPECT_EQ(summaries(single), summaries(whole));
    EXPECT_EQ(single.drops, whole.drops);
    EXPECT_EQ(single.rejections, whole.rejections);
    EXPECT_EQ(single.rejection_offsets, whole.rejection_offsets);
    for (std::uint32_t seed = 1; seed <= 5; ++seed) {
      const Decoded random = decode(*stream, Chunking::kRandom, seed);
      EXPECT_EQ(summaries(random), summaries(whole)) << "seed " << seed;
      EXPECT_EQ(random.drops, whole.drops) << "seed " << seed;
      EXPECT_EQ(random.rejections, whole.rejections) << "seed " << seed;
    }
  }
}

TEST(SickCola, StampIsTheArrivalOfTheFirstStx) {
  const Bytes run = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
  StaticDecoder<> decoder;
  const std::span<const std::uint8_t> bytes(run);
  EXPECT_EQ(decoder.push(bytes.first(5), 111).telegram, nullptr);
  const Decoder::Step step = decoder.push(bytes.subspan(5), 222);
  ASSERT_NE(step.telegram, nullptr);
  EXPECT_EQ(step.telegram->stamp_ns, 111);
}

TEST(SickCola, TelegramFoundInsideRejectedBytesKeepsItsOwnStampAndOffset) {
  // A false start at t=100 claims 256 bytes; a real telegram arrives inside them at t=200; the
  // rest arrives at t=300, the false frame's checksum fails, and the real one is found again.
  const Bytes false_start = hex_bytes("02 02 02 02 00 00 01 00");
  const Bytes run = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
  const Bytes filler(300, 0x55);
  StaticDecoder<> decoder;
  std::vector<std::pair<std::string, TimestampNs>> events;
  std::vector<std::uint64_t> offsets;
  const auto feed = [&](std::span<const std::uint8_t> chunk, TimestampNs stamp) {
    for (;;) {
      const Decoder::Step step = decoder.push(chunk, stamp);
      chunk = chunk.subspan(step.consumed);
      if (step.telegram != nullptr) {
        events.emplace_back(std::string(step.telegram->command), step.telegram->stamp_ns);
        offsets.push_back(step.telegram->start_offset);
      }
      if (step.rejected) {
        events.emplace_back(to_string(step.reason), stamp);
        offsets.push_back(step.start_offset);
      }
      if (chunk.empty() && !step.has_event()) break;
    }
  };
  feed(false_start, 100);
  feed(run, 200);
  feed(filler, 300);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].first, "bad_checksum");
  EXPECT_EQ(offsets[0], 0u);
  EXPECT_EQ(events[1].first, "Run");
  EXPECT_EQ(events[1].second, 200);
  EXPECT_EQ(offsets[1], false_start.size());
  // Only the false header is the rejected telegram's; the filler is then skipped as garbage.
  EXPECT_EQ(decoder.drops().value(DropReason::kGarbage), filler.size());
  EXPECT_EQ(decoder.dropped_bytes(), filler.size() + false_start.size());
}

// --- corruption

TEST(SickCola, FalseStartPatternInsideGarbageHidesNoTelegram) {
  const Bytes frames = all16();
  const Bytes run = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
  // Claims 8192 bytes: covers the next two commands and two whole scans.
  Bytes garbage = blockmap::testing::random_garbage(100, 3);
  std::replace(garbage.begin(), garbage.end(), std::uint8_t{0x02}, std::uint8_t{0x55});
  const Bytes stream = concat({garbage, hex_bytes("02 02 02 02 00 00 20 00"), run, run,
                               frame(frames, 0), frame(frames, 1), frame(frames, 2)});
  const Decoded decoded = decode(stream);
  ASSERT_EQ(decoded.telegrams.size(), 5u);
  EXPECT_EQ(decoded.scans.size(), 3u);
  EXPECT_EQ(decoded.drop(DropReason::kBadChecksum), 1u);
  EXPECT_EQ(decoded.rejection_offsets.front(), 100u);
  EXPECT_EQ(decoded.telegrams[0].start_offset, 108u);
}

TEST(SickCola, ImpossibleLengthIsRejectedAtOnce) {
  const Bytes frames = all16();
  const Decoded decoded = decode(
      concat({hex_bytes("02 02 02 02 FF FF FF FF 02 02 02 02 00 00 00 00"), frame(frames, 0)}));
  EXPECT_EQ(decoded.drop(DropReason::kBadLength), 2u);
  ASSERT_EQ(decoded.scans.size(), 1u);
  EXPECT_EQ(decoded.telegrams[0].start_offset, 16u);
}

TEST(SickCola, CutOffTelegramThenGoodOnes) {
  const Bytes frames = all16();
  const Decoded decoded =
      decode(concat({frame(frames, 0).first(1700), frame(frames, 1), frame(frames, 2)}));
  ASSERT_EQ(decoded.scans.size(), 2u);
  EXPECT_EQ(decoded.telegrams[0].start_offset, 1700u);
  EXPECT_EQ(decoded.infos[0].scan_counter + 1, decoded.infos[1].scan_counter);
  EXPECT_EQ(decoded.drop(DropReason::kBadChecksum), 1u);
  EXPECT_EQ(decoded.dropped_bytes, 1700u);
}

TEST(SickCola, FlushRejectsAnUnfinishedTelegramAndFindsWhatItHid) {
  const Bytes frames = all16();
  // The cut-off telegram claims more than remains: only the end of input reveals it.
  const Bytes run = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
  const Decoded decoded = decode(concat({frame(frames, 0).first(1000), run, run}));
  EXPECT_EQ(decoded.drop(DropReason::kTruncated), 1u);
  ASSERT_EQ(decoded.telegrams.size(), 2u);
  EXPECT_EQ(decoded.telegrams[0].start_offset, 1000u);
  EXPECT_EQ(decoded.telegrams[1].command, "Run");
  EXPECT_EQ(decoded.buffered_after_flush, 0u);
}

TEST(SickCola, GarbageAroundTelegramsIsCountedAndSkipped) {
  const Bytes frames = all16();
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    const Bytes garbage = blockmap::testing::random_garbage(200 + seed * 13, seed);
    const Decoded decoded =
        decode(concat({garbage, frame(frames, 0), garbage, frame(frames, 1), garbage}),
               Chunking::kRandom, seed);
    ASSERT_EQ(decoded.scans.size(), 2u) << "seed " << seed;
    EXPECT_EQ(decoded.dropped_bytes, 3 * garbage.size()) << "seed " << seed;
    EXPECT_GT(decoded.drop(DropReason::kGarbage), 0u) << "seed " << seed;
  }
}

TEST(SickCola, DamagedStreamsNeverCrashAndStayInSync) {
  const Bytes frames = all16();
  const Bytes clean = Bytes(frame(frames, 0).begin(), frame(frames, 0).end());
  const std::string clean_summary = scan_summary(decode(clean).scans.at(0));
  for (std::uint32_t seed = 1; seed <= 40; ++seed) {
    std::size_t faults = 1 + seed % 4;
    Bytes damaged = seed % 2 == 0 ? blockmap::testing::flip_random_bits(frames, faults, seed)
                                  : blockmap::testing::drop_random_bytes(frames, 0.0001, seed);
    if (seed % 2 != 0) {
      faults = frames.size() - damaged.size();  // each lost byte costs at most one telegram
    }
    damaged.resize(damaged.size() - seed * 37 % 500);  // cut off inside the last telegram
    const Decoded decoded = decode(concat({damaged, clean}), Chunking::kRandom, seed);
    ASSERT_FALSE(decoded.scans.empty()) << "seed " << seed;
    EXPECT_EQ(scan_summary(decoded.scans.back()), clean_summary) << "seed " << seed;
    EXPECT_GE(decoded.scans.size(), 16u - faults) << "seed " << seed;
    EXPECT_GT(decoded.dropped_bytes, 0u) << "seed " << seed << ": the cut-off was not counted";
    EXPECT_EQ(decoded.buffered_after_flush, 0u);
  }
}

TEST(SickCola, ColaAFaultsAreRejectedByReason) {
  Config config;
  config.framing = Framing::kColaA;
  const Bytes stream = concat({bytes_of("\x02sRA LMDsc"), bytes_of("\x02sAN Run 1\x03"),
                               bytes_of("\x02sAN Ru\x01n\x03"), bytes_of("\x02sAN Run 1\x03"),
                               bytes_of("\x02\x03"), bytes_of("\x02sAN Run 1\x03")});
  const Decoded decoded = decode(stream, Chunking::kWhole, 1, config);
  EXPECT_EQ(decoded.telegrams.size(), 3u);
  EXPECT_EQ(decoded.rejections,
            (std::vector<DropReason>{DropReason::kTruncated, DropReason::kBadCharacter,
                                     DropReason::kMalformed}));
  EXPECT_EQ(decoded.drop(DropReason::kGarbage), 2u) << "the 'n' and the ETX after it";
}

TEST(SickCola, ColaATelegramLongerThanTheBufferIsRejected) {
  Config config;
  config.framing = Framing::kColaA;
  const Bytes stream = concat({bytes_of("\x02sRA "), Bytes(kDefaultTelegramCapacityBytes, 'A'),
                               bytes_of("\x03"), bytes_of("\x02sAN Run 1\x03")});
  const Decoded decoded = decode(stream, Chunking::kRandom, 3, config);
  ASSERT_EQ(decoded.telegrams.size(), 1u);
  EXPECT_EQ(decoded.telegrams[0].command, "Run");
  EXPECT_EQ(decoded.rejections, std::vector<DropReason>{DropReason::kTooLong});
}

Bytes scan_with_beams(Dialect dialect, std::uint16_t beams) {
  return encoded([&](auto out) {
    TelegramWriter w(dialect, out, "sSN", "LMDscandata");
    w.u16(1).u16(1).u32(7).u8(0).u8(0).u16(1).u16(2).u32(3).u32(4).u8(0).u8(0).u8(0).u8(0);
    w.u16(0).u32(2500).u32(540).u16(0).u16(1);
    w.name("DIST1").f32(1.0F).f32(0.0F).i32(-50000).u16(1667).u16(beams);
    for (std::uint16_t i = 0; i < beams; ++i) w.u16(1000);
    w.u16(0).u16(0).u16(0).u16(0).u16(0).u16(0);
    return w.finish();
  });
}

TEST(SickCola, ScansWithTooManyBeamsAreRejectedAndCounted) {
  for (const Dialect dialect : {Dialect::kColaB, Dialect::kColaA}) {
    const Bytes too_many = scan_with_beams(dialect, msg::kMaxLaserBeams + 1);
    const Bytes most = scan_with_beams(dialect, msg::kMaxLaserBeams);
    const Decoded decoded = decode(concat({too_many, most}));
    EXPECT_EQ(decoded.rejections, std::vector<DropReason>{DropReason::kTooManyBeams});
    ASSERT_EQ(decoded.scans.size(), 1u);
    EXPECT_EQ(decoded.scans[0].beam_count, msg::kMaxLaserBeams);
    EXPECT_FLOAT_EQ(decoded.scans[0].ranges_m[msg::kMaxLaserBeams - 1], 1.0F);
  }
}

TEST(SickCola, MalformedTelegramsAreRejected) {
  const auto frame_b = [](std::string_view body) {
    Bytes out(body.size() + 9);
    out.resize(frame_cola_b(bytes_of(body), out));
    return out;
  };
  const Bytes short_scan = frame_b(std::string_view("sSN LMDscandata \x00\x01\x00\x01", 20));
  const Bytes not_cola = frame_b("hello");
  const Bytes no_distance = encoded([](auto out) {
    TelegramWriter w(Dialect::kColaB, out, "sRA", "LMDscandata");
    w.u16(1).u16(1).u32(7).u8(0).u8(0).u16(1).u16(2).u32(3).u32(4).u8(0).u8(0).u8(0).u8(0);
    w.u16(0).u32(2500).u32(540).u16(0).u16(1);
    w.name("RSSI1").f32(1.0F).f32(0.0F).i32(-50000).u16(1667).u16(2).u16(5).u16(6);
    w.u16(0);
    return w.finish();
  });
  const Bytes run = encoded([](auto out) { return encode_run(Dialect::kColaB, out); });
  const Decoded decoded = decode(concat({short_scan, not_cola, no_distance, run}));
  EXPECT_EQ(decoded.rejections, std::vector<DropReason>(3, DropReason::kMalformed));
  ASSERT_EQ(decoded.telegrams.size(), 1u);
  EXPECT_EQ(decoded.telegrams[0].command, "Run");
}

// --- construction

TEST(SickCola, DecoderTakesItsBufferFromTheArena) {
  Arena arena(std::size_t{64} * 1024);
  Config config;
  config.telegram_capacity_bytes = 4096;
  Decoder decoder(arena, config);
  EXPECT_EQ(decoder.capacity_bytes(), 4096u);
  EXPECT_GE(arena.used_bytes(), 4096u);
  EXPECT_EQ(decoder.memory_bytes(), 4096u + sizeof(Decoder));
  const Bytes frames = all16();
  std::span<const std::uint8_t> rest = frame(frames, 0);
  std::size_t scans = 0;
  while (!rest.empty()) {
    const Decoder::Step step = decoder.push(rest, 1);
    rest = rest.subspan(step.consumed);
    scans += step.scan != nullptr ? 1U : 0U;
  }
  EXPECT_EQ(scans, 1u);
}

TEST(SickCola, TooSmallBufferIsAPreconditionFailure) {
  blockmap::testing::ThrowOnCheckFailure throwing;
  std::array<std::uint8_t, 16> storage{};
  EXPECT_THROW({ const Decoder decoder{std::span<std::uint8_t>(storage)}; },
               blockmap::testing::CheckFailedError);
}

}  // namespace
}  // namespace blockmap::hal::protocol::sick_cola
