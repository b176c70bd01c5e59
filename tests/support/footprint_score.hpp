// Footprints against truth: the intersection over union of two simple polygons (rasterized
// at a few centimetres: exact enough for the 0.8-0.95 thresholds the tests hold, and
// correct for the concave L and T).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>

#include <Eigen/Core>

#include "blockmap/planes/polygon.hpp"

namespace blockmap::testing {

inline double footprint_iou(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b,
                            double cell_m = 0.05) {
  if (a.size() < 3 || b.size() < 3) {
    return 0.0;
  }
  Eigen::Vector2d lo = a[0];
  Eigen::Vector2d hi = a[0];
  for (const auto polygon : {a, b}) {
    for (const Eigen::Vector2d& p : polygon) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  std::size_t both = 0;
  std::size_t either = 0;
  for (double y = lo.y() + 0.5 * cell_m; y < hi.y(); y += cell_m) {
    for (double x = lo.x() + 0.5 * cell_m; x < hi.x(); x += cell_m) {
      const bool in_a = planes::inside_polygon({x, y}, a);
      const bool in_b = planes::inside_polygon({x, y}, b);
      both += (in_a && in_b) ? 1U : 0U;
      either += (in_a || in_b) ? 1U : 0U;
    }
  }
  return either == 0 ? 0.0 : static_cast<double>(both) / static_cast<double>(either);
}

}  // namespace blockmap::testing
