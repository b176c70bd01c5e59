// The `--origin LAT,LON,HEIGHT` option of `replay` and `import`: where the local frame is on
// Earth, in degrees and metres above the WGS-84 ellipsoid.
#pragma once

#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>

#include "blockmap/hal/geodesy.hpp"

namespace blockmap::cli {

inline constexpr const char* kOriginFormatError =
    "--origin must be LAT,LON,HEIGHT in degrees and metres (latitude within 90, longitude "
    "within 180, height -1000 to 10000 m)";

// Heights above the ellipsoid a robot can be at: from the Dead Sea's shore to above Everest.
inline constexpr double kMinHeightM = -1000.0;
inline constexpr double kMaxHeightM = 10000.0;

// "A,B,C": three finite numbers and nothing after them, or nothing.
inline std::optional<std::array<double, 3>> parse_three_numbers(const std::string& text) {
  std::array<double, 3> values{};
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &values[0], &values[1], &values[2], &tail) != 3 ||
      !std::isfinite(values[0]) || !std::isfinite(values[1]) || !std::isfinite(values[2])) {
    return std::nullopt;
  }
  return values;
}

// The point, or nothing when the text is not three numbers or not a place on Earth.
inline std::optional<hal::GeodeticPoint> parse_origin(const std::string& text) {
  const std::optional<std::array<double, 3>> values = parse_three_numbers(text);
  if (!values || std::abs((*values)[0]) > 90.0 || std::abs((*values)[1]) > 180.0 ||
      (*values)[2] < kMinHeightM || (*values)[2] > kMaxHeightM) {
    return std::nullopt;
  }
  return hal::GeodeticPoint{(*values)[0], (*values)[1], (*values)[2]};
}

}  // namespace blockmap::cli
