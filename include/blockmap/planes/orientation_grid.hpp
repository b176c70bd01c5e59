// The (theta, phi) half of the Hough grid: plane normals on the upper half sphere, in bands of
// constant theta (the angle from +z) with as many phi cells per band as its circumference
// holds, so that cells have about equal area and the pole is not over-weighted.
//
// A plane's normal n and -n describe the same plane (d changes sign). The grid keeps z >= 0;
// on the equator band (vertical planes), where both n and -n have z ~ 0, it keeps phi in
// [0, pi). Two cells that are neighbours through that identification are "flipped": the
// same plane has offset d in one and -d in the other.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/planes_config.hpp"

namespace blockmap::planes {

class OrientationGrid {
 public:
  static constexpr std::size_t kMaxNeighbours = 16;
  static constexpr std::int32_t kNotSearched = -1;

  struct Neighbour {
    std::uint32_t row = 0;
    bool flipped = false;
  };

  // Cells of angle_bin_deg; `mode` selects which cells are searched. Each searched cell is a
  // row of the Hough accumulator. Every cell gets two vote kernels, computed once here: the
  // searched rows within kernel_deg of it (a surface with that normal votes for them) and the
  // searched rows perpendicular to it (a line in that direction lies in those planes).
  // kSizesOnly takes from the arena exactly what kFull takes, but leaves the kernels and
  // neighbours empty (half the work): a budget measured at start-up, not a grid to use.
  enum class Contents : std::uint8_t { kFull, kSizesOnly };
  void init(Arena& arena, double angle_bin_deg, OrientationMode mode, double tolerance_deg,
            double kernel_deg, Contents contents = Contents::kFull);

  [[nodiscard]] std::size_t cell_count() const noexcept { return cell_normal_.size(); }
  [[nodiscard]] std::size_t row_count() const noexcept { return row_cell_.size(); }
  [[nodiscard]] float angle_bin_rad() const noexcept { return band_step_rad_; }

  // The cell a normal (either sign, unit length) falls in.
  [[nodiscard]] std::uint32_t cell_of(const Eigen::Vector3f& normal) const noexcept;
  // The accumulator row of a cell, or kNotSearched.
  [[nodiscard]] std::int32_t row_of_cell(std::uint32_t cell) const noexcept {
    return cell_row_[cell];
  }
  [[nodiscard]] const Eigen::Vector3f& row_normal(std::uint32_t row) const noexcept {
    return cell_normal_[row_cell_[row]];
  }
  // What row_normal() reads: every cell's normal, and each row's cell.
  [[nodiscard]] std::span<const Eigen::Vector3f> cell_normals() const noexcept {
    return cell_normal_;
  }
  [[nodiscard]] std::span<const std::uint32_t> row_cells() const noexcept { return row_cell_; }
  [[nodiscard]] std::span<const std::uint32_t> surface_kernel(std::uint32_t cell) const noexcept {
    return flat_.subspan(surface_first_[cell], surface_first_[cell + 1] - surface_first_[cell]);
  }
  [[nodiscard]] std::span<const std::uint32_t> line_kernel(std::uint32_t cell) const noexcept {
    return flat_.subspan(line_first_[cell], line_first_[cell + 1] - line_first_[cell]);
  }
  // Searched rows whose cells are next to this row's (for non-maximum suppression).
  [[nodiscard]] std::span<const Neighbour> neighbours(std::uint32_t row) const noexcept;

  // Visits every searched row whose cell normal is within radius_rad of `normal` (or of
  // -normal), each once: visit(row). At most `limit` rows; returns how many it visited.
  template <typename Visit>
  std::size_t visit_rows_within(const Eigen::Vector3f& normal, float radius_rad, std::size_t limit,
                                Visit&& visit) const;

  // Every row whose cell normal is perpendicular to `direction` within half a cell: the
  // planes that contain a line. Visits each row once.
  template <typename Visit>
  void visit_rows_perpendicular_to(const Eigen::Vector3f& direction, Visit&& visit) const;

  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  // Calls visit(cell) for the cells of `band` whose phi range comes within half_width_rad of
  // phi_rad (cells may repeat across the two passes of visit_rows_within; it dedups).
  template <typename Visit>
  void visit_band_cells_near(std::uint32_t band, float phi_rad, float half_width_rad,
                             Visit&& visit) const;
  void build_neighbours();
  // searched_height_: whether a normal whose |z| falls in a bin may lie in a searched cell,
  // so that the line kernels skip the rest of each circle without finding its cells.
  static constexpr std::size_t kHeightBins = 1024;
  void mark_searched_heights(Arena& arena);
  [[nodiscard]] bool may_be_searched(const Eigen::Vector3f& n) const noexcept {
    const auto bin = static_cast<std::size_t>(std::abs(n.z()) * static_cast<float>(kHeightBins));
    return searched_height_[std::min(bin, kHeightBins - 1)] != 0;
  }
  void build_kernels(Arena& arena, float kernel_rad, Contents contents);

  std::uint32_t band_count_ = 0;  // bands 0 (the pole) .. band_count_ - 1 (the equator)
  float band_step_rad_ = 0.0f;
  float inverse_band_step_ = 0.0f;  // bands per radian
  std::span<std::uint32_t> band_first_cell_;
  std::span<std::uint32_t> band_cells_;
  std::span<Eigen::Vector3f> cell_normal_;
  std::span<std::int32_t> cell_row_;
  std::span<std::uint32_t> row_cell_;
  std::span<Neighbour> neighbour_table_;  // kMaxNeighbours per row
  std::span<std::uint8_t> neighbour_count_;
  std::span<std::uint32_t> surface_first_;  // per cell, into flat_ (one past the end too)
  std::span<std::uint32_t> line_first_;
  std::span<std::uint32_t> flat_;
  std::span<std::uint8_t> searched_height_;
};

// ---- templates ----

template <typename Visit>
void OrientationGrid::visit_band_cells_near(std::uint32_t band, float phi_rad, float half_width_rad,
                                            Visit&& visit) const {
  constexpr float kTwoPi = 6.28318530717958647692f;
  constexpr float kPi = 3.14159265358979323846f;
  const std::uint32_t cells = band_cells_[band];
  const bool equator = band + 1 == band_count_;
  const float span = equator ? kPi : kTwoPi;
  const float width = span / static_cast<float>(cells);
  if (2.0f * half_width_rad + width >= span || cells <= 3) {
    for (std::uint32_t j = 0; j < cells; ++j) {
      visit(band_first_cell_[band] + j);
    }
    return;
  }
  const auto first = static_cast<std::int64_t>(std::floor((phi_rad - half_width_rad) / width));
  const auto last = static_cast<std::int64_t>(std::floor((phi_rad + half_width_rad) / width));
  const auto count = static_cast<std::int64_t>(cells);
  for (std::int64_t j = first; j <= last; ++j) {
    const std::int64_t wrapped = ((j % count) + count) % count;
    visit(band_first_cell_[band] + static_cast<std::uint32_t>(wrapped));
  }
}

template <typename Visit>
std::size_t OrientationGrid::visit_rows_within(const Eigen::Vector3f& normal, float radius_rad,
                                               std::size_t limit, Visit&& visit) const {
  constexpr std::size_t kMaxVisited = 256;
  std::array<std::uint32_t, kMaxVisited> visited{};
  std::size_t visited_count = 0;
  const std::size_t capacity = limit < kMaxVisited ? limit : kMaxVisited;
  const float cos_radius = std::cos(radius_rad);
  for (const float sign : {1.0f, -1.0f}) {
    const Eigen::Vector3f n = sign * normal;
    const float theta = std::acos(std::clamp(n.z(), -1.0f, 1.0f));
    const float phi = std::atan2(n.y(), n.x());
    const auto lowest =
        static_cast<std::int64_t>(std::floor((theta - radius_rad) / band_step_rad_ + 0.5f));
    const auto highest =
        static_cast<std::int64_t>(std::floor((theta + radius_rad) / band_step_rad_ + 0.5f));
    for (std::int64_t band = std::max<std::int64_t>(lowest, 0);
         band <= std::min<std::int64_t>(highest, band_count_ - 1); ++band) {
      const float band_theta = static_cast<float>(band) * band_step_rad_;
      const float sin_theta = std::sin(band_theta);
      const float half_width = sin_theta > radius_rad
                                   ? std::asin(std::min(1.0f, std::sin(radius_rad) / sin_theta))
                                   : 4.0f;
      visit_band_cells_near(
          static_cast<std::uint32_t>(band), phi, half_width, [&](std::uint32_t cell) {
            const std::int32_t row = cell_row_[cell];
            if (row < 0 || std::abs(cell_normal_[cell].dot(normal)) < cos_radius) {
              return;
            }
            const auto row_index = static_cast<std::uint32_t>(row);
            for (std::size_t i = 0; i < visited_count; ++i) {
              if (visited[i] == row_index) {
                return;
              }
            }
            if (visited_count < capacity) {
              visited[visited_count++] = row_index;
              visit(row_index);
            }
          });
    }
  }
  return visited_count;
}

template <typename Visit>
void OrientationGrid::visit_rows_perpendicular_to(const Eigen::Vector3f& direction,
                                                  Visit&& visit) const {
  // Normals perpendicular to the line: n(a) = cos(a) u + sin(a) v for a in [0, pi), sampled
  // at a third of a cell: the circle can only skip a cell it grazes at a corner.
  const Eigen::Vector3f line = direction.normalized();
  const Eigen::Vector3f helper =
      std::abs(line.z()) < 0.9f ? Eigen::Vector3f::UnitZ() : Eigen::Vector3f::UnitX();
  const Eigen::Vector3f u = line.cross(helper).normalized();
  const Eigen::Vector3f v = line.cross(u);
  constexpr float kPi = 3.14159265358979323846f;
  const auto steps = static_cast<std::uint32_t>(std::ceil(3.0f * kPi / band_step_rad_));
  // The circle stays in a cell for several steps and may graze a corner and come back: a
  // cell is skipped when it is one of the last few visited (or the first, where it ends).
  constexpr std::size_t kRecent = 4;
  std::array<std::uint32_t, kRecent> recent{};
  recent.fill(static_cast<std::uint32_t>(-1));
  std::size_t recent_next = 0;
  auto first_cell = static_cast<std::uint32_t>(-1);
  for (std::uint32_t i = 0; i < steps; ++i) {
    const float a = kPi * static_cast<float>(i) / static_cast<float>(steps);
    const Eigen::Vector3f n = std::cos(a) * u + std::sin(a) * v;
    if (!may_be_searched(n)) {
      continue;  // a part of the circle far from every searched row
    }
    const std::uint32_t cell = cell_of(n);
    if (cell == first_cell || std::find(recent.begin(), recent.end(), cell) != recent.end()) {
      continue;
    }
    recent[recent_next] = cell;
    recent_next = (recent_next + 1) % kRecent;
    if (i == 0) {
      first_cell = cell;
    }
    const std::int32_t row = cell_row_[cell];
    if (row >= 0) {
      visit(static_cast<std::uint32_t>(row));
    }
  }
}

}  // namespace blockmap::planes
