// Recorded logs with damage a robot's disk or a copy can give them (issue 55): one corrupt
// record of each kind in a 20 s run maps as the undamaged run does, and says what it skipped;
// a whole run with one byte in a thousand damaged keeps most of its walls.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "blockmap_process.hpp"
#include "scratch.hpp"
#include "test_data.hpp"

namespace blockmap::testing {
namespace {

namespace fs = std::filesystem;

std::string bytes_of(const fs::path& path) {
  return read_text(path);
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

ProcessLimits minutes(double timeout_s) {
  ProcessLimits limits;
  limits.timeout_s = timeout_s;
  return limits;
}

std::size_t plane_count(const fs::path& out) {
  return nlohmann::json::parse(read_text(out / "planes.json"))["planes"].size();
}

// The offset of the byte log's record that starts at or after `at` (walking the records).
std::size_t record_at_or_after(const std::string& log, std::size_t at) {
  std::size_t offset = 8;  // the magic
  while (offset + 16 <= log.size() && offset < at) {
    std::uint32_t length = 0;
    for (int i = 3; i >= 0; --i) {
      length =
          (length << 8) | static_cast<std::uint8_t>(log[offset + 8 + static_cast<std::size_t>(i)]);
    }
    offset += 16 + length;
  }
  return offset;
}

class DamagedLogs : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = scratch("damaged_logs");
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const ProcessResult run = run_process(
        BLOCKMAP_EXE, {"simulate", "--world", "benning", "--duration-s", "20", "--out", "log"},
        dir_, minutes(120.0));
    ASSERT_EQ(run.status, 0) << run.err;
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

TEST_F(DamagedLogs, OneCorruptRecordOfEachKindMapsAsTheWholeLogDoesAndIsReported) {
  const ProcessResult whole =
      run_process(BLOCKMAP_EXE, {"replay", "log", "--out", "whole"}, dir_, minutes(300.0));
  ASSERT_EQ(whole.status, 0) << whole.err;

  fs::copy(dir_ / "log", dir_ / "damaged");
  // A CAN time 1e8 s ahead (one digit of one line), a third of the way in.
  std::string can = bytes_of(dir_ / "damaged" / "rmp.candump");
  const std::size_t line = can.find("\n(", can.size() / 3) + 1;
  ASSERT_EQ(can.substr(line, 3), "(11");
  can[line + 2] = '2';
  write_bytes(dir_ / "damaged" / "rmp.candump", can);
  // In each laser's log a flipped bit in a record's header and another in a record's bytes.
  for (const char* name : {"laser_horizontal.bytelog", "laser_vertical.bytelog"}) {
    std::string log = bytes_of(dir_ / "damaged" / name);
    log[record_at_or_after(log, log.size() / 3) + 13] ^= 0x04;  // a reserved byte
    log[record_at_or_after(log, 2 * log.size() / 3) + 20] ^= 0x10;
    write_bytes(dir_ / "damaged" / name, log);
  }
  // A broken NMEA sentence.
  std::string nmea = bytes_of(dir_ / "damaged" / "gps.nmea");
  const std::size_t sentence = nmea.find("$GPGGA", nmea.size() / 3);
  nmea.replace(sentence + 10, 12, "garbage#####");
  write_bytes(dir_ / "damaged" / "gps.nmea", nmea);

  const ProcessResult damaged = run_process(
      BLOCKMAP_EXE, {"replay", "damaged", "--out", "damaged_map"}, dir_, minutes(300.0));
  ASSERT_EQ(damaged.status, 0) << damaged.err;
  const std::size_t planes = plane_count(dir_ / "whole");
  EXPECT_GT(planes, 5u);
  EXPECT_NEAR(static_cast<double>(plane_count(dir_ / "damaged_map")), static_cast<double>(planes),
              1.0);
  EXPECT_NE(damaged.err.find("CAN log times: 1 off both neighbours"), std::string::npos)
      << damaged.err;
  for (const char* name : {"laser_horizontal", "laser_vertical"}) {
    EXPECT_NE(damaged.err.find(std::string(name) + ".bytelog: 1 damaged places skipped"),
              std::string::npos)
        << damaged.err;
  }
}

// A log missing, empty or not a file: one line, and the run goes on when it can.
struct LogFault {
  const char* what;
  const char* log;
  enum { kRemove, kEmpty, kFolder, kNoise } fault;
  int status;
  const char* says;  // in the last line for a failure, in a warning for a success
};

TEST_F(DamagedLogs, ALogMissingEmptyOrNotAFileIsOneLine) {
  const LogFault faults[] = {
      {"no CAN log", "rmp.candump", LogFault::kRemove, 1, "rmp.candump: cannot open"},
      {"an empty CAN log", "rmp.candump", LogFault::kEmpty, 1, "no status group of the base"},
      {"noise for a CAN log", "rmp.candump", LogFault::kNoise, 1, "no status group of the base"},
      {"a folder for the CAN log", "rmp.candump", LogFault::kFolder, 1, "is a folder"},
      {"a folder for the NMEA log", "gps.nmea", LogFault::kFolder, 1, "is a folder"},
      {"an empty NMEA log", "gps.nmea", LogFault::kEmpty, 1, "holds no usable fix"},
      {"an empty laser log", "laser_vertical.bytelog", LogFault::kEmpty, 0,
       "mapping without that laser"},
      {"noise for a laser log", "laser_vertical.bytelog", LogFault::kNoise, 0,
       "mapping without that laser"},
  };
  std::mt19937 draw(3);
  for (const LogFault& f : faults) {
    SCOPED_TRACE(f.what);
    const fs::path logs = dir_ / "fault";
    fs::remove_all(logs);
    fs::copy(dir_ / "log", logs);
    fs::remove(logs / f.log);
    if (f.fault == LogFault::kFolder) {
      fs::create_directories(logs / f.log);
    } else if (f.fault != LogFault::kRemove) {
      std::string bytes(f.fault == LogFault::kNoise ? 4096 : 0, '\0');
      for (char& byte : bytes) {
        byte = static_cast<char>(draw());
      }
      write_bytes(logs / f.log, bytes);
    }
    const ProcessResult r =
        run_process(BLOCKMAP_EXE, {"replay", "fault", "--out", "fault_map"}, dir_, minutes(60.0));
    ASSERT_TRUE(r.exited) << r.err;
    EXPECT_EQ(r.status, f.status) << r.err;
    const std::size_t end = r.err.find_last_not_of('\n');
    const std::string last = r.err.substr(r.err.rfind('\n', end) + 1);
    if (f.status != 0) {
      EXPECT_EQ(last.rfind("blockmap: replay: ", 0), 0u) << r.err;
      EXPECT_NE(last.find(f.says), std::string::npos) << r.err;
    } else {
      EXPECT_NE(r.err.find(std::string("warning: fault/") + f.log), std::string::npos) << r.err;
      EXPECT_NE(r.err.find(f.says), std::string::npos) << r.err;
    }
  }
}

TEST_F(DamagedLogs, PlayOnARandomCanLogWithNobodyReadingKeepsItsPace) {
  fs::copy(dir_ / "log", dir_ / "random_can");
  std::mt19937 draw(1);
  std::string noise(100000, '\0');
  for (char& byte : noise) {
    byte = static_cast<char>(draw());
  }
  write_bytes(dir_ / "random_can" / "rmp.candump", noise);
  // 20 s of logs at ten times their pace: 2 s, though the CAN log gives no clock and nobody
  // reads the lines.
  const ProcessResult played =
      run_process(BLOCKMAP_EXE, {"play", "random_can", "--pty-dir", "ptys", "--speed", "10"}, dir_,
                  minutes(10.0));
  ASSERT_FALSE(played.timed_out) << played.err;
  EXPECT_EQ(played.status, 0) << played.err;
  EXPECT_NE(played.err.find("play: 20.0"), std::string::npos) << played.err;
}

// One bit flipped in one byte of every thousand, the bytes and bits drawn by `draw`.
void flip_one_byte_in_a_thousand(const fs::path& log, std::mt19937& draw) {
  std::string bytes = bytes_of(log);
  std::uniform_int_distribution<std::size_t> byte(0, bytes.size() - 1);
  std::uniform_int_distribution<int> bit(0, 7);
  for (std::size_t i = 0; i < bytes.size() / 1000; ++i) {
    const int flipped = bit(draw);
    char& target = bytes[byte(draw)];
    target = static_cast<char>(target ^ (1 << flipped));
  }
  write_bytes(log, bytes);
}

std::vector<nlohmann::json> walls_of(const fs::path& out) {
  std::vector<nlohmann::json> walls;
  const nlohmann::json list = nlohmann::json::parse(read_text(out / "planes.json"));
  for (const nlohmann::json& plane : list["planes"]) {
    if (plane["kind"] == "wall") {
      walls.push_back(plane);
    }
  }
  return walls;
}

// Whether one of `walls` is `wall`: within 3 degrees, 0.15 m off its plane, its centre near.
bool has_wall(const std::vector<nlohmann::json>& walls, const nlohmann::json& wall) {
  const auto vec = [](const nlohmann::json& v) {
    return std::array<double, 3>{v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
  };
  const std::array<double, 3> n = vec(wall["normal"]);
  const std::array<double, 3> c = vec(wall["centroid"]);
  for (const nlohmann::json& other : walls) {
    const std::array<double, 3> m = vec(other["normal"]);
    const std::array<double, 3> d = vec(other["centroid"]);
    const double cosine = n[0] * m[0] + n[1] * m[1] + n[2] * m[2];
    const double off_m = n[0] * (d[0] - c[0]) + n[1] * (d[1] - c[1]) + n[2] * (d[2] - c[2]);
    if (std::abs(cosine) >= std::cos(3.0 * M_PI / 180.0) && std::abs(off_m) <= 0.15 &&
        std::hypot(d[0] - c[0], d[1] - c[1]) <= 10.0) {
      return true;
    }
  }
  return false;
}

TEST(DamagedRun, OneByteInAThousandFlippedInEveryLogKeepsFourFifthsOfTheWalls) {
  const fs::path dir = scratch("damaged_run");
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_EQ(
      run_process(BLOCKMAP_EXE, {"simulate", "--world", "benning", "--seed", "2", "--out", "log"},
                  dir, minutes(300.0))
          .status,
      0);
  // Both maps in the world's frame, whatever the damaged receiver's first fix.
  const nlohmann::json origin =
      nlohmann::json::parse(read_text(dir / "log" / "truth.json"))["origin"];
  const std::string anchor = std::to_string(origin["latitude_deg"].get<double>()) + "," +
                             std::to_string(origin["longitude_deg"].get<double>()) + "," +
                             std::to_string(origin["height_m"].get<double>());
  const ProcessResult whole = run_process(
      BLOCKMAP_EXE, {"replay", "log", "--out", "whole", "--origin", anchor}, dir, minutes(600.0));
  ASSERT_EQ(whole.status, 0) << whole.err;
  const std::vector<nlohmann::json> walls = walls_of(dir / "whole");
  ASSERT_GT(walls.size(), 15u);
  for (const unsigned seed : {1u, 2u, 3u}) {
    const fs::path damaged = dir / ("damaged_" + std::to_string(seed));
    fs::copy(dir / "log", damaged);
    std::mt19937 draw(seed);
    for (const char* name :
         {"rmp.candump", "gps.nmea", "laser_horizontal.bytelog", "laser_vertical.bytelog"}) {
      flip_one_byte_in_a_thousand(damaged / name, draw);
    }
    const fs::path out = damaged.string() + "_map";
    const ProcessResult run = run_process(
        BLOCKMAP_EXE, {"replay", damaged.string(), "--out", out.string(), "--origin", anchor}, dir,
        minutes(600.0));
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_NE(run.err.find("damaged places skipped"), std::string::npos) << run.err;
    const std::vector<nlohmann::json> found = walls_of(out);
    const auto kept = static_cast<std::size_t>(
        std::count_if(walls.begin(), walls.end(),
                      [&](const nlohmann::json& wall) { return has_wall(found, wall); }));
    std::cout << "damage " << seed << ": " << kept << " of " << walls.size() << " walls kept\n";
    EXPECT_GE(5 * kept, 4 * walls.size());
  }
  fs::remove_all(dir);
}

TEST(DamagedCapture, OneChangedByteInACoLaCaptureCostsOnlyItsSegment) {
  BLOCKMAP_SHARED_DATA_OR_SKIP(capture, "real/sick-cola-captures/20210302_lms111.pcapng.json");
  const fs::path dir = scratch("damaged_cola");
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::string text = bytes_of(capture);
  // A hex digit of a payload in the middle of the capture turned into a letter that is not one.
  const std::size_t payload = text.find(R"("tcp.payload": ")", text.size() / 2);
  ASSERT_NE(payload, std::string::npos);
  text[payload + 20] = 'Z';
  write_bytes(dir / "damaged.pcapng.json", text);
  const ProcessResult whole =
      run_process(BLOCKMAP_EXE, {"decode", "cola", capture.string()}, dir, minutes(60.0));
  const ProcessResult damaged =
      run_process(BLOCKMAP_EXE, {"decode", "cola", "damaged.pcapng.json"}, dir, minutes(60.0));
  ASSERT_EQ(damaged.status, 0) << damaged.err;
  EXPECT_NE(whole.err.find("cola: 277 telegrams decoded"), std::string::npos) << whole.err;
  EXPECT_NE(damaged.err.find("cola: 276 telegrams decoded"), std::string::npos) << damaged.err;
  EXPECT_NE(damaged.err.find("1 damaged and left out"), std::string::npos) << damaged.err;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace blockmap::testing
