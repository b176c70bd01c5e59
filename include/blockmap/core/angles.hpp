// Angles, one way for the whole project: radians inside, degrees only where people read or
// write them (configuration, device protocols, reports).
#pragma once

#include <cmath>
#include <numbers>

namespace blockmap {

inline constexpr double kRadiansPerDegree = std::numbers::pi / 180.0;
inline constexpr double kDegreesPerRadian = 180.0 / std::numbers::pi;

[[nodiscard]] constexpr double radians_from_degrees(double degrees) noexcept {
  return degrees * kRadiansPerDegree;
}

[[nodiscard]] constexpr double degrees_from_radians(double radians) noexcept {
  return radians * kDegreesPerRadian;
}

// The same direction in [-pi, pi]; IEEE remainder is exact, so a wrapped sum drifts by nothing.
[[nodiscard]] inline double wrap_angle(double angle_rad) noexcept {
  return std::remainder(angle_rad, 2.0 * std::numbers::pi);
}

}  // namespace blockmap
