// Recorded logs with damage a robot's disk or a copy can give them (issue 55): one corrupt
// record of each kind in a 20 s run maps as the undamaged run does, and says what it skipped.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
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
