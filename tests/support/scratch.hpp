// Where a test writes its files: the system's temporary folder, named by the test's own name
// and the process (ctest runs every test case in a process of its own, so two never meet).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

namespace blockmap::testing {

[[nodiscard]] inline std::filesystem::path scratch(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         ("blockmap_" + name + "_" + std::to_string(::getpid()));
}

}  // namespace blockmap::testing
