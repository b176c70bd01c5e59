#include "toml_reader.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "blockmap/hal/files.hpp"

namespace blockmap::hal::config {
namespace {

// Configuration files are a few kilobytes; a bigger one is not a configuration.
constexpr std::size_t kMaxConfigBytes = std::size_t{1} << 20;

// toml++ 3.3 (Debian's) reaches an unreachable point on some non-ASCII characters where it
// looks for whitespace (marzer/tomlplusplus#190, #295), and where it looks depends on how it
// reads damaged text (`e=0'` then one: a quote after a value is no string to it). A
// configuration is ASCII throughout, comments and strings too, so toml++ never meets one.
void refuse_non_ascii(std::string_view text, std::string_view source) {
  const auto found = std::find_if(text.begin(), text.end(),
                                  [](char c) { return static_cast<unsigned char>(c) >= 0x80; });
  if (found != text.end()) {
    const auto line = 1 + std::count(text.begin(), found, '\n');
    throw ConfigError(std::string(source) + ":" + std::to_string(line) +
                      ": a non-ASCII character (configuration files are ASCII)");
  }
}

}  // namespace

toml::table parse_document(std::string_view text, std::string_view source) {
  refuse_non_ascii(text, source);
  try {
    return toml::parse(text, source);
  } catch (const toml::parse_error& error) {
    std::ostringstream message;
    message << source << ':' << error.source().begin.line << ':' << error.source().begin.column
            << ": " << error.description();
    throw ConfigError(message.str());
  }
}

void refuse_unknown_tables(const toml::table& document, std::string_view source) {
  // Every table of config/README.md, "On the robot" and "Mapping".
  static constexpr std::array<std::string_view, 14> kTables = {
      "planes",     "buildings",    "window",    "projection",    "free_space",
      "rigid_path", "loop_closure", "prior_map", "scan_matching", "registry",
      "mapper",     "robot",        "devices",   "daemon"};
  for (const auto& [key, node] : document) {
    if (std::find(kTables.begin(), kTables.end(), key.str()) == kTables.end()) {
      throw ConfigError(std::string(source) + ": " + std::string(key.str()) + ": " +
                        (node.is_table() ? "unknown table" : "unknown key") +
                        " (config/README.md lists the tables)");
    }
    if (!node.is_table()) {
      throw ConfigError(std::string(source) + ": " + std::string(key.str()) + ": must be a table");
    }
  }
}

std::string read_config_file(const std::filesystem::path& path) {
  try {
    return read_whole_file(path, kMaxConfigBytes);
  } catch (const FileError& error) {
    throw ConfigError(error.what());
  }
}

std::string builtin_or_file_text(std::span<const std::string_view> names,
                                 std::span<const std::string_view> texts,
                                 std::string_view name_or_path, std::string_view kind,
                                 std::string& source) {
  const bool is_path =
      name_or_path.find('/') != std::string_view::npos || name_or_path.ends_with(".toml");
  if (!is_path) {
    std::string known;
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (names[i] == name_or_path) {
        source = std::string(name_or_path) + ".toml";
        return std::string(texts[i]);
      }
      known += known.empty() ? "" : ", ";
      known += names[i];
    }
    throw ConfigError("no built-in " + std::string(kind) + " '" + std::string(name_or_path) +
                      "' (there " + (names.size() == 1 ? "is " : "are ") + known +
                      "; or give a .toml file)");
  }
  source = std::string(name_or_path);
  return read_config_file(std::filesystem::path(name_or_path));
}

TableReader::TableReader(const toml::table& table, std::string source, std::string path)
    : table_(&table), source_(std::move(source)), path_(std::move(path)) {}

std::string TableReader::key_path(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

void TableReader::fail(std::string_view key, std::string_view what) const {
  throw ConfigError(source_ + ": " + key_path(key) + ": " + std::string(what));
}

void TableReader::reject(std::string_view problem) const {
  throw ConfigError(source_ + ": " + std::string(problem));
}

bool TableReader::has(std::string_view key) const {
  return table_->contains(key);
}

const toml::node* TableReader::find(std::string_view key) {
  read_.emplace(key);
  return table_->get(key);
}

double TableReader::number(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail(key, "missing (a number is required)");
  }
  if (const auto value = node->value<double>();
      value && (node->is_floating_point() || node->is_integer())) {
    if (!std::isfinite(*value)) {
      fail(key, "must be a finite number");
    }
    return *value;
  }
  fail(key, "expected a number");
}

double TableReader::number_or(std::string_view key, double fallback) {
  if (!has(key)) {
    read_.emplace(key);
    return fallback;
  }
  return number(key);
}

std::int64_t TableReader::integer(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail(key, "missing (an integer is required)");
  }
  if (!node->is_integer()) {
    fail(key, "expected an integer");
  }
  return *node->value<std::int64_t>();
}

std::int64_t TableReader::integer_or(std::string_view key, std::int64_t fallback) {
  if (!has(key)) {
    read_.emplace(key);
    return fallback;
  }
  return integer(key);
}

std::size_t TableReader::capacity_or(std::string_view key, std::size_t fallback) {
  const std::int64_t value = integer_or(key, static_cast<std::int64_t>(fallback));
  // Far above any capacity a robot uses, and low enough that the bytes of two of them
  // multiplied stay a number on a 64-bit machine.
  constexpr std::int64_t kMaxCapacity = std::int64_t{1} << 24;
  if (value < 1 || value > kMaxCapacity) {
    fail(key, "must be 1 to 16777216");
  }
  return static_cast<std::size_t>(value);
}

bool TableReader::boolean_or(std::string_view key, bool fallback) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    return fallback;
  }
  if (!node->is_boolean()) {
    fail(key, "expected true or false");
  }
  return *node->value<bool>();
}

std::string TableReader::string(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail(key, "missing (a string is required)");
  }
  if (!node->is_string()) {
    fail(key, "expected a string");
  }
  return *node->value<std::string>();
}

std::string TableReader::string_or(std::string_view key, std::string_view fallback) {
  if (!has(key)) {
    read_.emplace(key);
    return std::string(fallback);
  }
  return string(key);
}

std::vector<std::string> TableReader::string_list_or_empty(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    read_.emplace(key);
    return {};
  }
  const toml::array* array = node->as_array();
  if (array == nullptr) {
    fail(key, "expected a list of strings");
  }
  std::vector<std::string> strings;
  for (std::size_t i = 0; i < array->size(); ++i) {
    const std::optional<std::string> text = (*array)[i].value<std::string>();
    if (!(*array)[i].is_string() || !text) {
      fail(std::string(key) + "[" + std::to_string(i) + "]", "expected a string");
    }
    strings.push_back(*text);
  }
  return strings;
}

template <int N>
Eigen::Matrix<double, N, 1> TableReader::fixed_vector(std::string_view key, const toml::node* node,
                                                      std::string_view shape,
                                                      std::string_view count) const {
  const std::string expected = "expected " + std::string(shape) + " (" + std::string(count) + ")";
  if (node == nullptr) {
    fail(key, "missing (" + std::string(shape) + " is required)");
  }
  const toml::array* array = node->as_array();
  if (array == nullptr || array->size() != N) {
    fail(key, expected);
  }
  Eigen::Matrix<double, N, 1> value;
  for (int i = 0; i < N; ++i) {
    const toml::node& element = (*array)[static_cast<std::size_t>(i)];
    if (!element.is_number()) {
      fail(key, expected);
    }
    value[i] = *element.value<double>();
  }
  if (!value.allFinite()) {
    fail(key, "must be finite");
  }
  return value;
}

double TableReader::unix_time(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail(key, "missing (a date-time such as 2006-05-10T17:00:00Z is required)");
  }
  const auto* stamp = node->as_date_time();
  if (stamp == nullptr || !stamp->get().offset) {
    fail(key, "expected a date-time with a UTC offset, such as 2006-05-10T17:00:00Z");
  }
  const toml::date_time& value = stamp->get();
  const std::chrono::year_month_day day{std::chrono::year{value.date.year},
                                        std::chrono::month{value.date.month},
                                        std::chrono::day{value.date.day}};
  if (!day.ok()) {
    fail(key, "not a calendar date");
  }
  const auto days = std::chrono::sys_days{day}.time_since_epoch().count();
  return static_cast<double>(days) * 86400.0 + value.time.hour * 3600.0 + value.time.minute * 60.0 +
         value.time.second + value.time.nanosecond * 1e-9 - value.offset->minutes * 60.0;
}

Eigen::Vector2d TableReader::vec2(std::string_view key) {
  return fixed_vector<2>(key, find(key), "[x, y]", "two numbers");
}

Eigen::Vector3d TableReader::vec3(std::string_view key) {
  return fixed_vector<3>(key, find(key), "[x, y, z]", "three numbers");
}

Eigen::Vector2d TableReader::vec2_or(std::string_view key, const Eigen::Vector2d& fallback) {
  if (!has(key)) {
    read_.emplace(key);
    return fallback;
  }
  return vec2(key);
}

std::vector<Eigen::Vector2d> TableReader::vec2_list(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail(key, "missing (a list of [x, y] pairs is required)");
  }
  const toml::array* array = node->as_array();
  if (array == nullptr) {
    fail(key, "expected a list of [x, y] pairs");
  }
  std::vector<Eigen::Vector2d> points;
  for (std::size_t i = 0; i < array->size(); ++i) {
    points.push_back(fixed_vector<2>(std::string(key) + "[" + std::to_string(i) + "]", &(*array)[i],
                                     "[x, y]", "two numbers"));
  }
  return points;
}

std::optional<TableReader> TableReader::table(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    return std::nullopt;
  }
  const toml::table* sub = node->as_table();
  if (sub == nullptr) {
    fail(key, "expected a table");
  }
  return TableReader(*sub, source_, key_path(key));
}

std::vector<TableReader> TableReader::tables(std::string_view key) {
  std::vector<TableReader> result;
  const toml::node* node = find(key);
  if (node == nullptr) {
    return result;
  }
  const toml::array* array = node->as_array();
  if (array == nullptr) {
    fail(key, "expected an array of tables ([[" + std::string(key) + "]])");
  }
  for (std::size_t i = 0; i < array->size(); ++i) {
    const toml::table* sub = (*array)[i].as_table();
    if (sub == nullptr) {
      fail(key, "expected an array of tables ([[" + std::string(key) + "]])");
    }
    result.emplace_back(*sub, source_, key_path(key) + "[" + std::to_string(i) + "]");
  }
  return result;
}

double TableReader::positive(std::string_view key, double value) const {
  if (!(value > 0.0)) {
    fail(key, "must be > 0");
  }
  return value;
}

double TableReader::non_negative(std::string_view key, double value) const {
  if (!(value >= 0.0)) {
    fail(key, "must be >= 0");
  }
  return value;
}

double TableReader::positive_or(std::string_view key, double fallback) {
  return positive(key, number_or(key, fallback));
}

double TableReader::non_negative_or(std::string_view key, double fallback) {
  return non_negative(key, number_or(key, fallback));
}

double TableReader::in_range(std::string_view key, double value, double low, double high) const {
  if (!(value >= low && value <= high)) {
    std::ostringstream what;
    what << "must lie in [" << low << ", " << high << "]";
    fail(key, what.str());
  }
  return value;
}

void TableReader::finish() const {
  for (const auto& [key, node] : *table_) {
    if (read_.find(key.str()) == read_.end()) {
      fail(key.str(), "unknown key");
    }
  }
}

}  // namespace blockmap::hal::config
