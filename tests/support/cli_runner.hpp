// Runs the blockmap command line in-process, as main() would, and keeps what it printed.
#pragma once

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "cli.hpp"

namespace blockmap::cli::testing {

struct CliResult {
  int status = 0;
  std::string out;
  std::string err;
};

// `args` without the program name: {"planes", "cloud.ply"}.
inline CliResult run_cli(const std::vector<std::string>& args) {
  std::vector<const char*> argv = {"blockmap"};
  for (const std::string& arg : args) {
    argv.push_back(arg.c_str());
  }
  std::ostringstream out;
  std::ostringstream err;
  const int status = run(static_cast<int>(argv.size()), argv.data(), out, err);
  return {status, out.str(), err.str()};
}

// The whole of a file the command wrote ("" when it is missing).
inline std::string read_file(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  std::ostringstream text;
  text << file.rdbuf();
  return text.str();
}

// The logs of `blockmap simulate ARGS...`, made once for every test process of this build and
// only read by the tests (ctest runs each test case in a process of its own, and a suite's
// SetUpTestSuite would simulate again in each). They live in the build tree, named by the
// arguments and the test program's own time stamp: a rebuilt simulator relinks the program, so
// a stale run is never reused. Two processes racing both simulate; the first rename wins.
// Returns an empty path, with the command's stderr in `err`, when the simulation fails.
inline std::filesystem::path simulated_logs(const std::vector<std::string>& args,
                                            std::string& err) {
  namespace fs = std::filesystem;
  std::string name = "sim";
  for (const std::string& arg : args) {
    name += '_';
    name += arg;
  }
  std::error_code error;
  const auto built = fs::last_write_time("/proc/self/exe", error).time_since_epoch();
  name += '_';
  name += std::to_string(std::chrono::duration_cast<std::chrono::seconds>(built).count());
  fs::path folder = fs::path(BLOCKMAP_TEST_CACHE_DIR) / name;  // returned: not const, moved
  if (fs::exists(folder / "truth.json")) {
    return folder;
  }
  fs::create_directories(folder.parent_path());
  const fs::path partial = folder.string() + ".partial" + std::to_string(::getpid());
  fs::remove_all(partial);
  std::vector<std::string> command = {"simulate"};
  command.insert(command.end(), args.begin(), args.end());
  command.insert(command.end(), {"--out", partial.string()});
  const CliResult result = run_cli(command);
  if (result.status != 0) {
    err = result.err;
    fs::remove_all(partial);
    return {};
  }
  fs::rename(partial, folder, error);  // fails when another process got there first
  fs::remove_all(partial);
  return folder;
}

}  // namespace blockmap::cli::testing
