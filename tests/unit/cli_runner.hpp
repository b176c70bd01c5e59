// Runs the blockmap command line in-process, as main() would, and keeps what it printed.
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
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

}  // namespace blockmap::cli::testing
