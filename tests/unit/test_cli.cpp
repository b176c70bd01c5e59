#include "cli.hpp"

#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

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

TEST(Cli, InfoRejectsStrayArguments) {
  const Result result = run_cli({"info", "extra"});
  EXPECT_EQ(result.status, kExitUsage);
}

}  // namespace
}  // namespace blockmap::cli
