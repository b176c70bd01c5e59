#include "cli.hpp"
#include "cli_runner.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "blockmap/hal/protocol/hokuyo_scip2.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "test_data.hpp"

namespace blockmap::cli {
namespace {

using Result = testing::CliResult;
using testing::run_cli;

std::size_t count_lines(const std::string& text) {
  std::size_t lines = 0;
  for (char c : text) {
    lines += (c == '\n') ? 1 : 0;
  }
  return lines;
}

TEST(Cli, VersionPrintsOneLineAndSucceeds) {
  const Result result = run_cli({"--version"});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_EQ(result.out.rfind("blockmap ", 0), 0u);
  EXPECT_EQ(count_lines(result.out), 1u);
  EXPECT_TRUE(result.err.empty());
}

TEST(Cli, HelpListsTheWorkingSubcommands) {
  const Result result = run_cli({"--help"});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_NE(result.out.find("info"), std::string::npos);
  EXPECT_NE(result.out.find("--version"), std::string::npos);
}

TEST(Cli, UnknownOptionIsOneLineOnStderrAndAUsageStatus) {
  const Result result = run_cli({"--frobnicate"});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_TRUE(result.out.empty());
  EXPECT_EQ(count_lines(result.err), 1u);
  EXPECT_EQ(result.err.rfind("blockmap: ", 0), 0u);
}

TEST(Cli, UnknownSubcommandIsAUsageError) {
  const Result result = run_cli({"teleport"});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_EQ(count_lines(result.err), 1u);
  EXPECT_NE(result.err.find("unknown subcommand 'teleport'"), std::string::npos) << result.err;
}

TEST(Cli, MissingSubcommandIsAUsageError) {
  const Result result = run_cli({});
  EXPECT_EQ(result.status, kExitUsage);
  EXPECT_EQ(count_lines(result.err), 1u);
}

TEST(Cli, InfoDescribesTheBuild) {
  const Result result = run_cli({"info"});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_NE(result.out.find("pointer_bits: "), std::string::npos);
  EXPECT_NE(result.out.find("lock_free_64bit_counters: yes"), std::string::npos);
}

TEST(Cli, DecodeNmeaWritesOneObjectPerPositionSentence) {
  const std::string log = blockmap::testing::project_data("nmea/gpsd_mtk-3329.log").string();
  const Result result = run_cli({"decode", "nmea", log});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_EQ(result.out.rfind("{\"sentence\":\"RMC\",\"talker\":\"GP\",\"time\":\"10:21:27.000\","
                             "\"date\":\"2011-02-21\",\"lat\":51.484371667,\"lon\":6.538185,",
                             0),
            0u)
      << result.out.substr(0, 200);
  EXPECT_EQ(count_lines(result.out), 9u) << "its RMC and GGA sentences";
  EXPECT_NE(result.err.find("nmea: 26 sentences decoded"), std::string::npos) << result.err;
}

TEST(Cli, DecodeReportsBadSentencesInLineAndGoesOn) {
  const std::string log = blockmap::testing::project_data("nmea/gpsd_garmin48.log").string();
  const Result result = run_cli({"decode", "nmea", log});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_NE(result.out.find("{\"error\":\"bad_checksum\",\"line\":84}"), std::string::npos);
  EXPECT_GT(result.out.find("{\"error\""), result.out.find("\"sentence\""));
  EXPECT_GT(result.out.rfind("\"sentence\""), result.out.find("{\"error\""));
}

TEST(Cli, DecodeRmpReadsCandumpAndOrcaLines) {
  const std::string log =
      blockmap::testing::project_data("segway_rmp/libsegwayrmp_unit_test_frames.txt").string();
  const Result result = run_cli({"decode", "rmp", log});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_EQ(count_lines(result.out), 6u);
  EXPECT_NE(result.out.find("\"id\":\"0x406\",\"operational_mode\":1,\"gain_schedule\":0,"
                            "\"ui_battery_v\":9.325,\"powerbase_battery_v\":78.0"),
            std::string::npos)
      << result.out;
}

TEST(Cli, DecodeColaWritesEveryRealScan) {
  const std::string capture =
      blockmap::testing::project_data("cola/sick_scan_xd_test_pcapng_all16_frames.bin").string();
  const Result result = run_cli({"decode", "cola", capture});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_EQ(count_lines(result.out), 16u);
  EXPECT_NE(result.out.find("\"beams\":811,\"start_deg\":-135.0"), std::string::npos);
  EXPECT_NE(result.err.find("16 scans"), std::string::npos) << result.err;
}

TEST(Cli, DecodeLms2xxAndScip2ReadTheirOwnEncodings) {
  // Per process: the four test trees run this test side by side.
  const std::filesystem::path dir = std::filesystem::temp_directory_path();
  const std::string unique = std::to_string(::getpid());
  std::vector<std::uint16_t> values(181, 1234);
  std::vector<std::uint8_t> telegram(900);
  const std::size_t n = hal::protocol::sick_lms2xx::encode_measured_values(
      telegram, values, hal::protocol::sick_lms2xx::Units::kCm, 0x00);
  const std::string lms_path = (dir / ("blockmap_cli_test_" + unique + ".lms")).string();
  std::ofstream(lms_path, std::ios::binary)
      .write(reinterpret_cast<const char*>(telegram.data()), static_cast<std::streamsize>(n));
  const Result lms = run_cli({"decode", "lms2xx", lms_path});
  EXPECT_EQ(lms.status, kExitOk);
  EXPECT_NE(lms.out.find("\"count\":181,\"units\":\"cm\""), std::string::npos)
      << lms.out.substr(0, 300);
  EXPECT_NE(lms.out.find("[12.34,12.34,"), std::string::npos);

  std::vector<char> reply(4096);
  const std::vector<std::uint32_t> ranges(11, 1500);
  const std::size_t m =
      hal::protocol::hokuyo_scip2::encode_scan_reply(reply, "GD0044005401", "00", 77, ranges);
  const std::string scip_path = (dir / ("blockmap_cli_test_" + unique + ".scip")).string();
  std::ofstream(scip_path, std::ios::binary).write(reply.data(), static_cast<std::streamsize>(m));
  const Result scip = run_cli({"decode", "scip2", scip_path});
  EXPECT_EQ(scip.status, kExitOk);
  EXPECT_NE(
      scip.out.find(
          "\"command\":\"GD0044005401\",\"status\":\"00\",\"sensor_time_ms\":77,\"beams\":11"),
      std::string::npos)
      << scip.out;
  std::filesystem::remove(lms_path);
  std::filesystem::remove(scip_path);
}

TEST(Cli, DecodeNeedsAKnownProtocolAndAReadableFile) {
  EXPECT_EQ(run_cli({"decode", "morse", "x"}).status, kExitUsage);
  const Result missing = run_cli({"decode", "nmea", "/nonexistent/capture.nmea"});
  EXPECT_EQ(missing.status, kExitFailure);
  EXPECT_EQ(count_lines(missing.err), 1u);
}

TEST(Cli, InfoRejectsStrayArguments) {
  const Result result = run_cli({"info", "extra"});
  EXPECT_EQ(result.status, kExitUsage);
}

}  // namespace
}  // namespace blockmap::cli
