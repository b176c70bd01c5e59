// Strict reading of TOML tables (private to hal/: the only place toml++ is included). Every
// value is read through a TableReader, which remembers the keys it was asked for; finish()
// then rejects any key nobody asked for, so a misspelt key or a wrong unit suffix
// ("height_ft") is an error naming it, never silently ignored.
#pragma once

#include <toml++/toml.h>

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "blockmap/hal/config/config_error.hpp"

namespace blockmap::hal::config {

// Parses a whole document; a syntax error becomes ConfigError "source:line:column: what".
[[nodiscard]] toml::table parse_document(std::string_view text, std::string_view source);

// A configuration file's text; ConfigError "path: cannot open" when it cannot be read.
[[nodiscard]] std::string read_config_file(const std::filesystem::path& path);

// A configuration named on the command line: a built-in one by name (`names[i]` -> `texts[i]`),
// or a file when it looks like a path (a '/' or a .toml ending). `kind` ("world", "robot")
// words the errors. Returns the text and sets `source` to the name messages should carry.
[[nodiscard]] std::string builtin_or_file_text(std::span<const std::string_view> names,
                                               std::span<const std::string_view> texts,
                                               std::string_view name_or_path, std::string_view kind,
                                               std::string& source);

// Refuses a table or key at the top of a mapping configuration (`--config`) that no reader
// knows: each command reads only its own tables of the file, so each also checks the rest.
void refuse_unknown_tables(const toml::table& document, std::string_view source);

class TableReader {
 public:
  // `path` is the table's key path for messages ("" for the document, "buildings[2]").
  TableReader(const toml::table& table, std::string source, std::string path);

  [[nodiscard]] bool has(std::string_view key) const;

  [[nodiscard]] double number(std::string_view key);  // integer or float
  [[nodiscard]] double number_or(std::string_view key, double fallback);
  [[nodiscard]] std::int64_t integer(std::string_view key);
  [[nodiscard]] std::int64_t integer_or(std::string_view key, std::int64_t fallback);
  // A capacity: a whole number >= 1 (fails naming the key otherwise).
  [[nodiscard]] std::size_t capacity_or(std::string_view key, std::size_t fallback);
  [[nodiscard]] bool boolean_or(std::string_view key, bool fallback);
  [[nodiscard]] std::string string(std::string_view key);
  [[nodiscard]] std::string string_or(std::string_view key, std::string_view fallback);
  // ["a", "b", ...]; empty when absent.
  [[nodiscard]] std::vector<std::string> string_list_or_empty(std::string_view key);
  // A TOML offset date-time, as Unix seconds.
  [[nodiscard]] double unix_time(std::string_view key);
  // [x, y]
  [[nodiscard]] Eigen::Vector2d vec2(std::string_view key);
  [[nodiscard]] Eigen::Vector2d vec2_or(std::string_view key, const Eigen::Vector2d& fallback);
  // [x, y, z]
  [[nodiscard]] Eigen::Vector3d vec3(std::string_view key);
  // [[x, y], ...]
  [[nodiscard]] std::vector<Eigen::Vector2d> vec2_list(std::string_view key);

  // A sub-table; none when absent.
  [[nodiscard]] std::optional<TableReader> table(std::string_view key);
  // An array of tables ([[key]]); empty when absent.
  [[nodiscard]] std::vector<TableReader> tables(std::string_view key);

  // Value checks that name the key.
  [[nodiscard]] double positive(std::string_view key, double value) const;
  [[nodiscard]] double non_negative(std::string_view key, double value) const;
  [[nodiscard]] double in_range(std::string_view key, double value, double low, double high) const;
  // number_or checked the same way: the key's value, or the fallback, must be > 0 (>= 0).
  [[nodiscard]] double positive_or(std::string_view key, double fallback);
  [[nodiscard]] double non_negative_or(std::string_view key, double fallback);

  // Throws for the first key that was never read.
  void finish() const;

  // "source: path.key: what"
  [[noreturn]] void fail(std::string_view key, std::string_view what) const;
  // "source: problem": what a stage's validate() found wrong with the table's values together.
  [[noreturn]] void reject(std::string_view problem) const;

 private:
  [[nodiscard]] const toml::node* find(std::string_view key);
  // `node` as N finite numbers, written `shape` ("[x, y]") of `count` ("two numbers") in
  // messages; fails naming `key`.
  template <int N>
  [[nodiscard]] Eigen::Matrix<double, N, 1> fixed_vector(std::string_view key,
                                                         const toml::node* node,
                                                         std::string_view shape,
                                                         std::string_view count) const;
  [[nodiscard]] std::string key_path(std::string_view key) const;

  const toml::table* table_;
  std::string source_;
  std::string path_;
  std::set<std::string, std::less<>> read_;
};

}  // namespace blockmap::hal::config
