#include "cli.hpp"

#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "test_data.hpp"

namespace blockmap::cli {
namespace {

struct Result {
  int status;
  std::string out;
  std::string err;
};

Result run_cli(std::vector<const char*> args) {
  args.insert(args.begin(), "blockmap");
  std::ostringstream out;
  std::ostringstream err;
  const int status = run(static_cast<int>(args.size()), args.data(), out, err);
  return {status, out.str(), err.str()};
}

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
  const Result result = run_cli({"decode", "nmea", log.c_str()});
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
  const Result result = run_cli({"decode", "nmea", log.c_str()});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_NE(result.out.find("{\"error\":\"bad_checksum\",\"line\":84}"), std::string::npos);
  EXPECT_GT(result.out.find("{\"error\""), result.out.find("\"sentence\""));
  EXPECT_GT(result.out.rfind("\"sentence\""), result.out.find("{\"error\""));
}

TEST(Cli, DecodeRmpReadsCandumpAndOrcaLines) {
  const std::string log =
      blockmap::testing::project_data("segway_rmp/libsegwayrmp_unit_test_frames.txt").string();
  const Result result = run_cli({"decode", "rmp", log.c_str()});
  EXPECT_EQ(result.status, kExitOk);
  EXPECT_EQ(count_lines(result.out), 6u);
  EXPECT_NE(result.out.find("\"id\":\"0x406\",\"operational_mode\":1,\"gain_schedule\":0,"
                            "\"ui_battery_v\":9.325,\"powerbase_battery_v\":78.0"),
            std::string::npos)
      << result.out;
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
