// Test data: tests/data (shipped, always present) and ../shared/data (beside the checkout in CI
// and on developers' machines; absent in a user's fresh clone, where such tests skip).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace blockmap::testing {

inline std::filesystem::path project_data(std::string_view relative) {
  return std::filesystem::path(BLOCKMAP_TEST_DATA_DIR) / relative;
}

// The path under ../shared/data, or nothing when that folder or file is absent.
inline std::optional<std::filesystem::path> shared_data(std::string_view relative) {
  const std::filesystem::path path = std::filesystem::path(BLOCKMAP_SHARED_DATA_DIR) / relative;
  if (!std::filesystem::exists(path)) {
    return std::nullopt;
  }
  return path;
}

inline std::vector<std::uint8_t> read_bytes(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  EXPECT_TRUE(file.good()) << "cannot open " << path;
  return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
}

inline std::string read_text(const std::filesystem::path& path) {
  const std::vector<std::uint8_t> bytes = read_bytes(path);
  return {bytes.begin(), bytes.end()};
}

}  // namespace blockmap::testing

// Declares `variable` as the path of `relative` under ../shared/data, or skips the test.
// (`variable` is the name declared, which cannot be in parentheses.)
// NOLINTBEGIN(bugprone-macro-parentheses)
#define BLOCKMAP_SHARED_DATA_OR_SKIP(variable, relative)                  \
  const std::optional<std::filesystem::path> variable##_or =              \
      ::blockmap::testing::shared_data(relative);                         \
  if (!variable##_or) {                                                   \
    GTEST_SKIP() << "../shared/data/" << (relative) << " is not present"; \
  }                                                                       \
  const std::filesystem::path& variable = *variable##_or
// NOLINTEND(bugprone-macro-parentheses)
