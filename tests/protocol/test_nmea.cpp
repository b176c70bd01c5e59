// NMEA 0183 codec: golden sentences, real receiver logs against gpsd's expected output,
// chunking invariance and corruption (docs/protocols.md section 5).
#include "blockmap/hal/protocol/nmea.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "byte_streams.hpp"
#include "test_data.hpp"

namespace blockmap::hal::protocol::nmea {
namespace {

using blockmap::testing::bytes_of;
using blockmap::testing::Chunking;

struct Decoded {
  std::vector<Sentence> sentences;
  std::vector<DropReason> rejections;
  std::array<std::uint64_t, static_cast<std::size_t>(DropReason::kCount)> drops{};
};

Decoded decode(std::span<const std::uint8_t> bytes, Chunking chunking = Chunking::kWhole,
               std::uint32_t seed = 1, const Config& config = {}) {
  Decoder decoder(config);
  Decoded result;
  TimestampNs stamp_ns = 0;
  blockmap::testing::feed_in_chunks(bytes, chunking, seed,
                                    [&](std::span<const std::uint8_t> chunk) {
                                      stamp_ns += 1000;
                                      while (!chunk.empty()) {
                                        const Decoder::Step step = decoder.push(chunk, stamp_ns);
                                        chunk = chunk.subspan(step.consumed);
                                        if (step.sentence != nullptr) {
                                          result.sentences.push_back(*step.sentence);
                                        }
                                        if (step.rejected) {
                                          result.rejections.push_back(step.reason);
                                        }
                                      }
                                    });
  for (std::size_t r = 0; r < result.drops.size(); ++r) {
    result.drops[r] = decoder.drops().value(static_cast<DropReason>(r));
  }
  return result;
}

Sentence decode_one(std::string_view line, const Config& config = {}) {
  const Decoded decoded = decode(bytes_of(line), Chunking::kWhole, 1, config);
  EXPECT_EQ(decoded.sentences.size(), 1u) << line;
  EXPECT_TRUE(decoded.rejections.empty()) << line;
  return decoded.sentences.empty() ? Sentence{} : decoded.sentences.front();
}

DropReason reject_one(std::string_view line) {
  const Decoded decoded = decode(bytes_of(line));
  EXPECT_TRUE(decoded.sentences.empty()) << line;
  EXPECT_EQ(decoded.rejections.size(), 1u) << line;
  return decoded.rejections.empty() ? DropReason::kCount : decoded.rejections.front();
}

// Everything a decoded sentence says except its receive stamp, for exact comparisons.
std::string summary(const Sentence& s) {
  std::ostringstream out;
  out.precision(17);
  const msg::GpsFix& f = s.fix;
  out << to_string(s.type) << ' ' << s.talker.data() << " @" << s.start_offset << " t" << f.has_time
      << ':' << f.utc_milliseconds_of_day << " d" << f.has_date << ':' << f.utc_year << '-'
      << int{f.utc_month} << '-' << int{f.utc_day} << " p" << f.has_position << ':'
      << f.latitude_deg << ',' << f.longitude_deg << " a" << f.has_altitude << ':'
      << f.altitude_msl_m << " q" << int{static_cast<std::uint8_t>(f.quality)} << " m"
      << int{static_cast<std::uint8_t>(f.mode)} << " s" << int{f.satellites_used} << " h" << f.hdop
      << " v" << f.speed_mps << " c" << f.course_deg << " ok" << f.valid << " gsa"
      << int{s.gsa.fix_type} << ':' << int{s.gsa.satellite_count} << " gsv"
      << int{s.gsv.block_count} << ':' << s.gsv.satellites_in_view;
  return out.str();
}

std::vector<std::string> summaries(const Decoded& decoded) {
  std::vector<std::string> lines;
  for (const Sentence& s : decoded.sentences) {
    lines.push_back(summary(s));
  }
  return lines;
}

constexpr std::int32_t hms_ms(int h, int m, int s, int ms = 0) {
  return ((h * 60 + m) * 60 + s) * 1000 + ms;
}

// --- golden sentences (docs/protocols.md 5.x; values as in vectors/nmea/decoded_examples.json)

TEST(Nmea, ChecksumWorkedExample) {
  const std::string_view body = "GPGLL,,,,,,V,N";
  EXPECT_EQ(checksum(std::span<const char>(body.data(), body.size())), 0x64);
}

TEST(Nmea, GgaWithAllFields) {
  const Sentence s =
      decode_one("$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n");
  EXPECT_EQ(s.type, SentenceType::kGga);
  EXPECT_STREQ(s.talker.data(), "GP");
  EXPECT_EQ(s.fix.utc_milliseconds_of_day, hms_ms(12, 35, 19));
  EXPECT_NEAR(s.fix.latitude_deg, 48.1173, 1e-12);
  EXPECT_NEAR(s.fix.longitude_deg, 11.516666666666667, 1e-12);
  EXPECT_EQ(s.fix.quality, msg::GpsFixQuality::kGps);
  EXPECT_EQ(s.fix.satellites_used, 8);
  EXPECT_DOUBLE_EQ(s.fix.hdop, 0.9);
  EXPECT_DOUBLE_EQ(s.fix.altitude_msl_m, 545.4);
  EXPECT_DOUBLE_EQ(s.fix.geoid_separation_m, 46.9);
  EXPECT_TRUE(s.fix.valid);
  EXPECT_FALSE(s.fix.has_date);
}

TEST(Nmea, RmcSouthernHemisphereWithDate) {
  const Sentence s =
      decode_one("$GPRMC,081836,A,3751.65,S,14507.36,E,000.0,360.0,130998,011.3,E*62\r\n");
  EXPECT_EQ(s.type, SentenceType::kRmc);
  EXPECT_NEAR(s.fix.latitude_deg, -37.86083333333333, 1e-12);
  EXPECT_NEAR(s.fix.longitude_deg, 145.12266666666667, 1e-12);
  EXPECT_DOUBLE_EQ(s.fix.speed_mps, 0.0);
  EXPECT_DOUBLE_EQ(s.fix.course_deg, 360.0);
  EXPECT_EQ(s.fix.utc_year, 1998);
  EXPECT_EQ(s.fix.utc_month, 9);
  EXPECT_EQ(s.fix.utc_day, 13);
  EXPECT_TRUE(s.fix.valid);
}

TEST(Nmea, MissingChecksumIsRejectedUnlessConfigured) {
  const std::string_view line =
      "$GPRMC,081836.75,A,3751.65,S,14507.36,E,000.0,360.0,130998,011.3,E\n";
  EXPECT_EQ(reject_one(line), DropReason::kMissingChecksum);
  Config lenient;
  lenient.accept_missing_checksum = true;
  const Sentence s = decode_one(line, lenient);
  EXPECT_EQ(s.fix.utc_milliseconds_of_day, hms_ms(8, 18, 36, 750));
  EXPECT_NEAR(s.fix.latitude_deg, -37.860833333, 1e-9);
}

TEST(Nmea, MultiConstellationRmcSpeedInMetresPerSecond) {
  const Sentence s =
      decode_one("$GNRMC,081411.000,A,5541.1955,N,03737.2872,E,0.60,301.29,260514,,,A*74\r\n");
  EXPECT_STREQ(s.talker.data(), "GN");
  EXPECT_NEAR(s.fix.latitude_deg, 55.686591666666665, 1e-12);
  EXPECT_NEAR(s.fix.longitude_deg, 37.621453333333335, 1e-12);
  EXPECT_NEAR(s.fix.speed_mps, 0.3086664, 1e-6);
  EXPECT_DOUBLE_EQ(s.fix.course_deg, 301.29);
  EXPECT_EQ(s.fix.utc_year, 2014);
}

TEST(Nmea, RtkGgaWithEightDecimalMinutesAndNegativeGeoid) {
  const Sentence s = decode_one(
      "$GNGGA,133900.00,4134.50180323,N,09345.03586581,W,4,19,0.7,280.827,M,-31.442,M,6.0,0002*"
      "61\r\n");
  EXPECT_NEAR(s.fix.latitude_deg, 41.57503005383334, 1e-12);
  EXPECT_NEAR(s.fix.longitude_deg, -93.7505977635, 1e-12);
  EXPECT_EQ(s.fix.quality, msg::GpsFixQuality::kRtkFixed);
  EXPECT_EQ(s.fix.satellites_used, 19);
  EXPECT_DOUBLE_EQ(s.fix.geoid_separation_m, -31.442);
  EXPECT_NEAR(s.fix.altitude_msl_m + s.fix.geoid_separation_m, 249.385, 1e-9);
}

TEST(Nmea, GgaThatStopsAfterTheGeoidField) {
  const Sentence s =
      decode_one("$GNGGA,001043.00,4404.14036,N,12118.85961,W,1,12,0.98,1113.0,M,-21.3,M*47\r\n");
  EXPECT_NEAR(s.fix.latitude_deg, 44.06900600000001, 1e-12);
  EXPECT_NEAR(s.fix.longitude_deg, -121.31432683333333, 1e-12);
  EXPECT_DOUBLE_EQ(s.fix.altitude_msl_m, 1113.0);
}

TEST(Nmea, GsaWithGapsInTheSatelliteList) {
  const Sentence s = decode_one("$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39\r\n");
  ASSERT_EQ(s.type, SentenceType::kGsa);
  EXPECT_TRUE(s.gsa.automatic);
  EXPECT_EQ(s.gsa.fix_type, 3);
  ASSERT_EQ(s.gsa.satellite_count, 5);
  EXPECT_EQ(s.gsa.satellite_ids[0], 4);
  EXPECT_EQ(s.gsa.satellite_ids[4], 24);
  EXPECT_DOUBLE_EQ(s.gsa.pdop, 2.5);
  EXPECT_DOUBLE_EQ(s.gsa.hdop, 1.3);
  EXPECT_DOUBLE_EQ(s.gsa.vdop, 2.1);
  EXPECT_FALSE(s.gsa.has_system_id);
}

TEST(Nmea, GsaWithNmea410SystemId) {
  const Sentence s = decode_one("$GNGSA,A,3,68,69,70,78,84,85,,,,,,,1.5,1.3,1.0,2*3D\r\n");
  EXPECT_EQ(s.gsa.satellite_count, 6);
  EXPECT_TRUE(s.gsa.has_system_id);
  EXPECT_EQ(s.gsa.system_id, 2);
}

TEST(Nmea, GsvWithAnEmptyFourthBlock) {
  const Sentence s = decode_one("$GPGSV,3,3,11,22,42,067,42,24,14,311,43,27,05,244,00,,,,*4D\r\n");
  ASSERT_EQ(s.type, SentenceType::kGsv);
  EXPECT_EQ(s.gsv.sentence_count, 3);
  EXPECT_EQ(s.gsv.sentence_number, 3);
  EXPECT_EQ(s.gsv.satellites_in_view, 11);
  ASSERT_EQ(s.gsv.block_count, 3);
  EXPECT_EQ(s.gsv.satellites[1].id, 24);
  EXPECT_EQ(s.gsv.satellites[1].azimuth_deg, 311);
  EXPECT_FLOAT_EQ(s.gsv.satellites[2].snr_db, 0.0F);
}

TEST(Nmea, GalileoGsvWithSignalId) {
  const Sentence s =
      decode_one("$GAGSV,2,1,07,36,76,149,45,09,47,142,50,04,40,062,35,11,26,120,44,7*73\r\n");
  EXPECT_STREQ(s.talker.data(), "GA");
  EXPECT_EQ(s.gsv.block_count, 4);
  EXPECT_TRUE(s.gsv.has_signal_id);
  EXPECT_EQ(s.gsv.signal_id, 7);
}

TEST(Nmea, BeidouTalkersBdAndGb) {
  EXPECT_STREQ(
      decode_one("$BDGSV,2,1,07,01,00,000,45,02,01,090,35,03,00,000,38,04,00,000,42*6A\r\n")
          .talker.data(),
      "BD");
  const Sentence gb =
      decode_one("$GBGSV,2,1,05,201,00,000,44,202,14,089,35,204,00,000,42,205,27,091,*66\r\n");
  EXPECT_STREQ(gb.talker.data(), "GB");
  EXPECT_EQ(gb.gsv.satellites[0].id, 201);
  EXPECT_FALSE(gb.gsv.satellites[3].has_snr);
}

TEST(Nmea, VtgSpeedAndCourses) {
  const Sentence s = decode_one("$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48\r\n");
  EXPECT_DOUBLE_EQ(s.fix.course_deg, 54.7);
  EXPECT_DOUBLE_EQ(s.vtg.course_magnetic_deg, 34.4);
  EXPECT_NEAR(s.fix.speed_mps, 5.5 * 1852.0 / 3600.0, 1e-12);
}

TEST(Nmea, GllWithTimeAndStatus) {
  const Sentence s = decode_one("$GPGLL,3723.2475,N,12158.3416,W,161229.487,A,A*41\r\n");
  EXPECT_NEAR(s.fix.latitude_deg, 37.387458333333335, 1e-12);
  EXPECT_NEAR(s.fix.longitude_deg, -121.97236, 1e-12);
  EXPECT_EQ(s.fix.utc_milliseconds_of_day, hms_ms(16, 12, 29, 487));
  EXPECT_TRUE(s.fix.valid);
}

TEST(Nmea, ZdaWithNegativeZone) {
  const Sentence s = decode_one("$GPZDA,160012.71,11,03,2004,-1,00*7D\r\n");
  EXPECT_EQ(s.fix.utc_milliseconds_of_day, hms_ms(16, 0, 12, 710));
  EXPECT_EQ(s.fix.utc_year, 2004);
  EXPECT_EQ(s.fix.utc_month, 3);
  EXPECT_EQ(s.fix.utc_day, 11);
  EXPECT_EQ(s.zda.zone_hours, -1);
  EXPECT_EQ(s.zda.zone_minutes, 0);
}

TEST(Nmea, Nmea41RmcWithNavigationalStatus) {
  const Sentence s =
      decode_one("$GNRMC,120213.000,A,5957.0062,N,01100.6429,E,0.00,0.00,310722,,,D,V*0A\r\n");
  EXPECT_NEAR(s.fix.latitude_deg, 59.95010333333333, 1e-12);
  EXPECT_NEAR(s.fix.longitude_deg, 11.010715000000001, 1e-12);
  EXPECT_TRUE(s.fix.valid);
}

TEST(Nmea, NoFixSentencesDecodeWithEverythingAbsent) {
  for (std::string_view line :
       {"$GPRMC,,V,,,,,,,,,,N*53\r\n", "$GPGGA,,,,,,0,00,99.99,,,,,,*48\r\n",
        "$GPGLL,,,,,,V,N*64\r\n", "$GNVTG,,,,,,,,,N*2E\r\n",
        "$GPGSA,A,1,,,,,,,,,,,,,99.99,99.99,99.99*30\r\n"}) {
    const Sentence s = decode_one(line);
    EXPECT_FALSE(s.fix.valid) << line;
    EXPECT_FALSE(s.fix.has_position) << line;
  }
  const Sentence timed = decode_one("$GNGGA,074150.799,,,,,0,00,,,M,0.0,M,,0000,*64\r\n");
  EXPECT_TRUE(timed.fix.has_time);
  EXPECT_EQ(timed.fix.utc_milliseconds_of_day, hms_ms(7, 41, 50, 799));
  EXPECT_FALSE(timed.fix.has_position);
  EXPECT_EQ(timed.fix.mode, msg::GpsFixMode::kNone);
}

TEST(Nmea, FixModeComesFromTheLatestGsa) {
  const Decoded decoded =
      decode(bytes_of("$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39\r\n"
                      "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"));
  ASSERT_EQ(decoded.sentences.size(), 2u);
  EXPECT_EQ(decoded.sentences[1].fix.mode, msg::GpsFixMode::k3d);
}

TEST(Nmea, BadChecksumsAreRejected) {
  EXPECT_EQ(reject_one("$GPGSV,3,1,11,01,78,221,47,03,09,042,00,04,05,242,00,06,04,149,00*7\r\n"),
            DropReason::kBadChecksum);
  EXPECT_EQ(reject_one("$GLGSV,3,3,09,88,07,028*51\r\n"), DropReason::kBadChecksum);
  EXPECT_EQ(reject_one("$GPRMC,,V,,,,,,,,,,N*532\r\n"), DropReason::kBadChecksum);
  EXPECT_EQ(reject_one("$GPXTE,A,A,0.67,L,N*6g\r\n"), DropReason::kBadChecksum);
}

TEST(Nmea, ProprietaryAndUnsupportedSentencesAreSkippedAndCounted) {
  const Decoded decoded =
      decode(bytes_of("$PGRME,10.3,M,15.2,M,16.7,M*1A\r\n$PMTK001,604,1*30\r\n$PERDAPI,ECLKCNT,"
                      "9999999.97232,Hz*37\r\n"
                      "$GPTXT,01,01,02,ANTSTATUS=INIT*25\r\n"));
  EXPECT_TRUE(decoded.sentences.empty());
  EXPECT_TRUE(decoded.rejections.empty());
  EXPECT_EQ(decoded.drops[static_cast<std::size_t>(DropReason::kProprietary)], 3u);
  EXPECT_EQ(decoded.drops[static_cast<std::size_t>(DropReason::kUnsupported)], 1u);
}

TEST(Nmea, MalformedFieldsAreRejected) {
  // Valid checksums over impossible contents: minutes >= 60, month 13, a letter in a number.
  const auto with_checksum = [](std::string body) {
    char star[8];
    std::snprintf(star, sizeof star, "*%02X\r\n",
                  checksum(std::span<const char>(body.data(), body.size())));
    return "$" + body + star;
  };
  for (const std::string body : {"GPGGA,123519,4867.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
                                 "GPRMC,081836,A,3751.65,S,14507.36,E,000.0,360.0,131398,011.3,E",
                                 "GPGGA,123519,4807.038,N,01131.000,E,1,0x,0.9,545.4,M,46.9,M,,",
                                 "GPGGA,123519,4807.038,Q,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
                                 "GPGGA,1235,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
                                 "GPGGA,123519,4807.038,N,01131.000,E,1,08,nan,545.4,M,46.9,M,,"}) {
    EXPECT_EQ(reject_one(with_checksum(body)), DropReason::kMalformed) << body;
  }
}

// Every sentence of vectors/nmea/decoded_examples.json: accepted exactly when its checksum is
// good, and where the file gives a position, the same position.
TEST(Nmea, SharedDecodedExamplesAgree) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(path, "vectors/nmea/decoded_examples.json");
  const nlohmann::json examples = nlohmann::json::parse(blockmap::testing::read_text(path));
  ASSERT_EQ(examples.size(), 28u);
  for (const nlohmann::json& example : examples) {
    const std::string line = example["sentence"].get<std::string>() + "\r\n";
    const Decoded decoded = decode(bytes_of(line));
    const bool has_checksum = !example["checksum_ok"].is_null();
    const bool proprietary = line[1] == 'P';
    if (has_checksum && example["checksum_ok"].get<bool>()) {
      EXPECT_TRUE(decoded.rejections.empty()) << line;
      EXPECT_EQ(decoded.sentences.size(), proprietary ? 0u : 1u) << line;
    } else {
      EXPECT_TRUE(decoded.sentences.empty()) << line;
      EXPECT_EQ(decoded.rejections.size(), 1u) << line;
    }
    const nlohmann::json& values = example["decoded"];
    if (decoded.sentences.size() == 1 && values.contains("lat") && !values["lat"].is_null()) {
      EXPECT_NEAR(decoded.sentences[0].fix.latitude_deg, values["lat"].get<double>(), 1e-9) << line;
      EXPECT_NEAR(decoded.sentences[0].fix.longitude_deg, values["lon"].get<double>(), 1e-9)
          << line;
    }
    if (decoded.sentences.size() == 1 && values.contains("speed_knots") &&
        !values["speed_knots"].is_null()) {
      EXPECT_NEAR(decoded.sentences[0].fix.speed_mps,
                  values["speed_knots"].get<double>() * 1852.0 / 3600.0, 1e-9)
          << line;
    }
  }
}

// --- the minmea validity sets (tests/data/nmea/minmea_validity_sets.txt)

std::string unescape(const std::string& line) {
  std::string out;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '\\' && i + 1 < line.size()) {
      const char next = line[i + 1];
      if (next == 'r') {
        out += '\r';
        ++i;
        continue;
      }
      if (next == 'n') {
        out += '\n';
        ++i;
        continue;
      }
      if (next == 'x' && i + 3 < line.size()) {
        out += static_cast<char>(std::stoi(line.substr(i + 2, 2), nullptr, 16));
        i += 3;
        continue;
      }
    }
    out += line[i];
  }
  return out;
}

std::map<std::string, std::vector<std::string>> read_minmea_sets() {
  std::istringstream file(blockmap::testing::read_text(
      blockmap::testing::project_data("nmea/minmea_validity_sets.txt")));
  std::map<std::string, std::vector<std::string>> sets;
  std::string section;
  std::string line;
  while (std::getline(file, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (line[0] == '[') {
      section = line;
      continue;
    }
    sets[section].push_back(unescape(line));
  }
  return sets;
}

TEST(Nmea, MinmeaValidSentencesAreAcceptedAndInvalidOnesAreNot) {
  auto sets = read_minmea_sets();
  ASSERT_EQ(sets["[valid_with_checksum]"].size(), 21u);
  for (const std::string& line : sets["[valid_with_checksum]"]) {
    const std::string terminated = line.back() == '\n' ? line : line + "\r\n";
    const Decoded decoded = decode(bytes_of(terminated));
    EXPECT_TRUE(decoded.rejections.empty()) << line;
  }
  Config lenient;
  lenient.accept_missing_checksum = true;
  for (const std::string& line : sets["[valid_without_checksum]"]) {
    const std::string terminated =
        (line.back() == '\n' || line.back() == '\r') ? line : line + "\r\n";
    EXPECT_TRUE(decode(bytes_of(terminated), Chunking::kWhole, 1, lenient).rejections.empty())
        << line;
  }
  ASSERT_EQ(sets["[invalid]"].size(), 11u);
  for (const std::string& line : sets["[invalid]"]) {
    const std::string terminated = line + "\r\n";
    const Decoded decoded = decode(bytes_of(terminated));
    const std::uint64_t garbage = decoded.drops[static_cast<std::size_t>(DropReason::kGarbage)];
    // A stray leading '$' is dropped as a truncated sentence; the valid sentence after it is
    // rightly decoded in a stream.
    EXPECT_TRUE(!decoded.rejections.empty() || garbage > 0) << line;
  }
}

// --- real receiver logs against gpsd's expected output (tests/data/nmea)

const char* const kGpsdLogs[] = {
    "gpsd_beidou-bd.log", "gpsd_beidou-gb.log", "gpsd_bu353-glonass.log",   "gpsd_furuno_gl_ga.log",
    "gpsd_garmin48.log",  "gpsd_mtk-3329.log",  "gpsd_nmea-fuzzy-cases.log"};

std::int32_t ms_of_iso_time(const std::string& iso) {  // "2014-05-26T08:14:11.000Z"
  const int h = std::stoi(iso.substr(11, 2));
  const int m = std::stoi(iso.substr(14, 2));
  const double s = std::stod(iso.substr(17, iso.size() - 18));
  return hms_ms(h, m, 0) + static_cast<std::int32_t>(std::lround(s * 1000.0));
}

TEST(Nmea, GpsdLogsMatchGpsdsPositionsAndTimes) {
  std::size_t checked = 0;
  for (const char* log : kGpsdLogs) {
    const std::string name = std::string("nmea/") + log;
    const Decoded decoded =
        decode(blockmap::testing::read_bytes(blockmap::testing::project_data(name)));
    std::multimap<std::int32_t, const msg::GpsFix*> fixes;
    for (const Sentence& s : decoded.sentences) {
      if (s.fix.has_position && s.fix.has_time) {
        fixes.emplace(s.fix.utc_milliseconds_of_day, &s.fix);
      }
    }
    std::istringstream expected(
        blockmap::testing::read_text(blockmap::testing::project_data(name + ".chk")));
    std::string line;
    while (std::getline(expected, line)) {
      if (line.rfind(R"({"class":"TPV")", 0) != 0) continue;
      const nlohmann::json tpv = nlohmann::json::parse(line);
      if (!tpv.contains("lat") || !tpv.contains("time")) continue;
      const std::int32_t ms = ms_of_iso_time(tpv["time"].get<std::string>());
      const auto [first, last] = fixes.equal_range(ms);
      bool matched = false;
      for (auto it = first; it != last; ++it) {
        matched =
            matched || (std::abs(it->second->latitude_deg - tpv["lat"].get<double>()) < 1e-8 &&
                        std::abs(it->second->longitude_deg - tpv["lon"].get<double>()) < 1e-8);
      }
      EXPECT_TRUE(matched) << log << ": gpsd reports " << line;
      ++checked;
    }
    // Every '$' sentence in the logs is valid except Garmin's one truncated sentence.
    const std::uint64_t bad_checksums =
        decoded.drops[static_cast<std::size_t>(DropReason::kBadChecksum)];
    EXPECT_EQ(bad_checksums, std::string(log) == "gpsd_garmin48.log" ? 1u : 0u) << log;
    EXPECT_EQ(decoded.drops[static_cast<std::size_t>(DropReason::kMalformed)], 0u) << log;
  }
  EXPECT_GT(checked, 50u) << "too few gpsd reports were compared";
}

// --- chunking invariance and corruption

TEST(Nmea, ResultDoesNotDependOnChunking) {
  for (const char* log : kGpsdLogs) {
    const auto bytes =
        blockmap::testing::read_bytes(blockmap::testing::project_data(std::string("nmea/") + log));
    const Decoded whole = decode(bytes, Chunking::kWhole);
    ASSERT_FALSE(whole.sentences.empty()) << log;
    const Decoded single = decode(bytes, Chunking::kByteByByte);
    EXPECT_EQ(summaries(single), summaries(whole)) << log;
    EXPECT_EQ(single.drops, whole.drops) << log;
    for (std::uint32_t seed = 1; seed <= 5; ++seed) {
      const Decoded random = decode(bytes, Chunking::kRandom, seed);
      EXPECT_EQ(summaries(random), summaries(whole)) << log << " seed " << seed;
      EXPECT_EQ(random.drops, whole.drops) << log << " seed " << seed;
      EXPECT_EQ(random.rejections, whole.rejections) << log << " seed " << seed;
    }
  }
}

TEST(Nmea, StampIsTheArrivalOfTheDollar) {
  Decoder decoder;
  const auto first = bytes_of("$GPGLL,,,,,");
  const auto second = bytes_of(",V,N*64\r\n");
  EXPECT_EQ(decoder.push(first, 111).sentence, nullptr);
  const Decoder::Step step = decoder.push(second, 222);
  ASSERT_NE(step.sentence, nullptr);
  EXPECT_EQ(step.sentence->fix.header.stamp_ns, 111);
}

const std::string_view kGoodGga =
    "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n";

TEST(Nmea, ResynchronisesAfterGarbageTruncationAndBadChecksums) {
  const auto garbage = blockmap::testing::random_garbage(500, 7);
  const std::vector<std::uint8_t> stream = blockmap::testing::concat(
      {bytes_of(kGoodGga), garbage, bytes_of("\r\n$GPGGA,1235"), bytes_of(kGoodGga),
       bytes_of("$GPGLL,,,,,,V,N*65\r\n"), bytes_of(kGoodGga), bytes_of(std::string(300, 'x')),
       bytes_of("$"), bytes_of(std::string(300, '1')), bytes_of(kGoodGga)});
  const Decoded decoded = decode(stream);
  std::size_t good = 0;
  for (const Sentence& s : decoded.sentences) {
    good += (s.type == SentenceType::kGga && s.fix.utc_milliseconds_of_day == hms_ms(12, 35, 19))
                ? 1U
                : 0U;
  }
  EXPECT_GE(good, 4u) << "a valid sentence after damage must always decode";
  EXPECT_GE(decoded.drops[static_cast<std::size_t>(DropReason::kTruncated)], 1u);
  EXPECT_GE(decoded.drops[static_cast<std::size_t>(DropReason::kBadChecksum)], 1u);
  EXPECT_GE(decoded.drops[static_cast<std::size_t>(DropReason::kTooLong)], 1u);
  EXPECT_GE(decoded.drops[static_cast<std::size_t>(DropReason::kGarbage)], 300u);
}

TEST(Nmea, DamagedLogsNeverCrashAndStayInSync) {
  const auto bytes =
      blockmap::testing::read_bytes(blockmap::testing::project_data("nmea/gpsd_furuno_gl_ga.log"));
  const std::vector<std::uint8_t> good = bytes_of(kGoodGga);
  for (std::uint32_t seed = 1; seed <= 40; ++seed) {
    std::vector<std::uint8_t> damaged =
        (seed % 2 == 0) ? blockmap::testing::flip_random_bits(bytes, 50, seed)
                        : blockmap::testing::drop_random_bytes(bytes, 0.01, seed);
    // Cut off mid-sentence (erase, not resize: gcc's -O1 sees resize's growing path).
    const std::size_t cut = std::min<std::size_t>(damaged.size(), seed * 37 % 200);
    damaged.erase(damaged.end() - static_cast<std::ptrdiff_t>(cut), damaged.end());
    const Decoded decoded = decode(blockmap::testing::concat({damaged, bytes_of("\r\n"), good}),
                                   Chunking::kRandom, seed);
    ASSERT_FALSE(decoded.sentences.empty()) << "seed " << seed;
    EXPECT_EQ(summary(decoded.sentences.back()).substr(0, 6), "GGA GP") << "seed " << seed;
    EXPECT_EQ(decoded.sentences.back().fix.utc_milliseconds_of_day, hms_ms(12, 35, 19))
        << "seed " << seed;
  }
}

}  // namespace
}  // namespace blockmap::hal::protocol::nmea
