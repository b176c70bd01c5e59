// What the scan matcher and the loop closer share: an occupancy grid's value between its cell
// centres, interpolated bilinearly, and its gradient (Hector SLAM's map access: Kohlbrecher et
// al., 2011), for Gauss-Newton on the grid. Private to src/localize.
#pragma once

#include <cmath>
#include <cstdint>

namespace blockmap::localize::bilinear {

struct Sample {
  double value = 0.0;
  double d_dx = 0.0;  // per metre
  double d_dy = 0.0;
};

// At (x_m, y_m), metres from the corner of cell (0, 0); `cell(x, y)` is a cell's value.
template <typename CellValue>
[[nodiscard]] Sample sample(double x_m, double y_m, double inverse_cell_m,
                            const CellValue& cell) noexcept {
  // Cell centres are the interpolation's nodes.
  const double u = x_m * inverse_cell_m - 0.5;
  const double v = y_m * inverse_cell_m - 0.5;
  const double floor_u = std::floor(u);
  const double floor_v = std::floor(v);
  const auto x = static_cast<std::int64_t>(floor_u);
  const auto y = static_cast<std::int64_t>(floor_v);
  const double fu = u - floor_u;
  const double fv = v - floor_v;
  const double m00 = cell(x, y);
  const double m10 = cell(x + 1, y);
  const double m01 = cell(x, y + 1);
  const double m11 = cell(x + 1, y + 1);
  Sample out;
  out.value = (1.0 - fv) * ((1.0 - fu) * m00 + fu * m10) + fv * ((1.0 - fu) * m01 + fu * m11);
  out.d_dx = ((1.0 - fv) * (m10 - m00) + fv * (m11 - m01)) * inverse_cell_m;
  out.d_dy = ((1.0 - fu) * (m01 - m00) + fu * (m11 - m10)) * inverse_cell_m;
  return out;
}

}  // namespace blockmap::localize::bilinear
