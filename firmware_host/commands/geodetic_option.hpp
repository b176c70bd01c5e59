// The `--origin LAT,LON,HEIGHT` option of `replay` and `import`: where the local frame is on
// Earth, in degrees and metres above the WGS-84 ellipsoid.
#pragma once

#include <cmath>
#include <cstdio>
#include <optional>
#include <string>

#include "blockmap/hal/geodesy.hpp"

namespace blockmap::cli {

inline constexpr const char* kOriginFormatError =
    "--origin must be LAT,LON,HEIGHT in degrees and metres";

// The point, or nothing when the text is not three numbers or not a place on Earth.
inline std::optional<hal::GeodeticPoint> parse_origin(const std::string& text) {
  hal::GeodeticPoint point;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &point.latitude_deg, &point.longitude_deg,
                  &point.height_m, &tail) != 3 ||
      std::abs(point.latitude_deg) > 90.0 || std::abs(point.longitude_deg) > 180.0) {
    return std::nullopt;
  }
  return point;
}

}  // namespace blockmap::cli
