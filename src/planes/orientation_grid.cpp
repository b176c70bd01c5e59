#include "blockmap/planes/orientation_grid.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/planes/fast_trig.hpp"

namespace blockmap::planes {
namespace {

constexpr double kPi = std::numbers::pi;

// Cells in band k: the circumference at theta_k over the cell width, at least one. The
// equator band holds half a circle (n and -n are the same plane there).
std::uint32_t cells_in_band(std::uint32_t band, std::uint32_t band_count, double step_rad) {
  if (band == 0) {
    return 1;
  }
  const double theta = static_cast<double>(band) * step_rad;
  const double circle = band + 1 == band_count ? kPi : 2.0 * kPi;
  return std::max<std::uint32_t>(
      1, static_cast<std::uint32_t>(std::lround(circle * std::sin(theta) / step_rad)));
}

bool searched(double theta_rad, OrientationMode mode, double tolerance_rad) {
  if (mode == OrientationMode::kAny) {
    return true;
  }
  return theta_rad <= tolerance_rad + 1e-9 || theta_rad >= kPi / 2.0 - tolerance_rad - 1e-9;
}

}  // namespace

void OrientationGrid::init(Arena& arena, double angle_bin_deg, OrientationMode mode,
                           double tolerance_deg, double kernel_deg, Contents contents) {
  BLOCKMAP_CHECK_MSG(angle_bin_deg > 0.0 && angle_bin_deg <= 30.0, "angle bin out of range");
  // A whole number of bands from the pole to the equator, the equator band centred on it.
  const auto intervals = static_cast<std::uint32_t>(std::lround(90.0 / angle_bin_deg));
  band_count_ = std::max<std::uint32_t>(intervals, 1) + 1;
  const double step_rad = kPi / 2.0 / static_cast<double>(band_count_ - 1);
  band_step_rad_ = static_cast<float>(step_rad);
  inverse_band_step_ = static_cast<float>(1.0 / step_rad);
  band_first_cell_ = arena.allocate_array<std::uint32_t>(band_count_, "planes.orientation_grid");
  band_cells_ = arena.allocate_array<std::uint32_t>(band_count_, "planes.orientation_grid");
  std::uint32_t cells = 0;
  for (std::uint32_t band = 0; band < band_count_; ++band) {
    band_first_cell_[band] = cells;
    band_cells_[band] = cells_in_band(band, band_count_, step_rad);
    cells += band_cells_[band];
  }
  cell_normal_ = arena.allocate_array<Eigen::Vector3f>(cells, "planes.orientation_grid");
  cell_row_ = arena.allocate_array<std::int32_t>(cells, "planes.orientation_grid");
  const double tolerance_rad = radians_from_degrees(tolerance_deg);
  std::uint32_t rows = 0;
  for (std::uint32_t band = 0; band < band_count_; ++band) {
    const double theta = static_cast<double>(band) * step_rad;
    const double circle = band + 1 == band_count_ ? kPi : 2.0 * kPi;
    for (std::uint32_t j = 0; j < band_cells_[band]; ++j) {
      const double phi = (static_cast<double>(j) + 0.5) * circle / band_cells_[band];
      const std::uint32_t cell = band_first_cell_[band] + j;
      cell_normal_[cell] = Eigen::Vector3d(std::sin(theta) * std::cos(phi),
                                           std::sin(theta) * std::sin(phi), std::cos(theta))
                               .cast<float>();
      cell_row_[cell] =
          searched(theta, mode, tolerance_rad) ? static_cast<std::int32_t>(rows++) : kNotSearched;
    }
  }
  row_cell_ = arena.allocate_array<std::uint32_t>(rows, "planes.orientation_grid");
  for (std::uint32_t cell = 0; cell < cells; ++cell) {
    if (cell_row_[cell] >= 0) {
      row_cell_[static_cast<std::uint32_t>(cell_row_[cell])] = cell;
    }
  }
  mark_searched_heights(arena);
  neighbour_table_ = arena.allocate_array<Neighbour>(
      static_cast<std::size_t>(rows) * kMaxNeighbours, "planes.orientation_grid");
  neighbour_count_ = arena.allocate_array<std::uint8_t>(rows, "planes.orientation_grid");
  if (contents == Contents::kFull) {
    build_neighbours();
  }
  build_kernels(arena, static_cast<float>(radians_from_degrees(kernel_deg)), contents);
}

void OrientationGrid::mark_searched_heights(Arena& arena) {
  // A bin of |z| may hold a searched cell when a band its theta range rounds to has a row
  // (the cells of a band are all searched or all not).
  searched_height_ = arena.allocate_array<std::uint8_t>(kHeightBins, "planes.orientation_grid");
  const auto band_at = [&](double theta_rad) {
    const double band = std::floor(theta_rad / static_cast<double>(band_step_rad_) + 0.5);
    return static_cast<std::uint32_t>(std::clamp(band, 0.0, static_cast<double>(band_count_ - 1)));
  };
  for (std::size_t bin = 0; bin < kHeightBins; ++bin) {
    const double z_low = static_cast<double>(bin) / kHeightBins;
    const double z_high = static_cast<double>(bin + 1) / kHeightBins;
    // One band either way of the range: float rounding in cell_of.
    const std::uint32_t first = band_at(std::acos(std::min(z_high, 1.0)));
    const std::uint32_t last = band_at(std::acos(z_low));
    bool any = false;
    for (std::uint32_t band = first == 0 ? 0 : first - 1;
         band <= std::min(last + 1, band_count_ - 1); ++band) {
      any = any || cell_row_[band_first_cell_[band]] >= 0;
    }
    searched_height_[bin] = any ? 1 : 0;
  }
}

void OrientationGrid::build_kernels(Arena& arena, float kernel_rad, Contents contents) {
  // Twice over the cells: count, then fill the flat table (sizes only: count).
  const std::size_t cells = cell_normal_.size();
  surface_first_ = arena.allocate_array<std::uint32_t>(cells + 1, "planes.orientation_grid");
  line_first_ = arena.allocate_array<std::uint32_t>(cells + 1, "planes.orientation_grid");
  std::size_t total = 0;
  for (std::size_t cell = 0; cell < cells; ++cell) {
    visit_rows_within(cell_normal_[cell], kernel_rad, 256, [&](std::uint32_t) { ++total; });
    visit_rows_perpendicular_to(cell_normal_[cell], [&](std::uint32_t) { ++total; });
  }
  flat_ = arena.allocate_array<std::uint32_t>(total, "planes.orientation_grid");
  if (contents == Contents::kSizesOnly) {
    return;
  }
  std::uint32_t next = 0;
  const auto append = [&](std::uint32_t row) { flat_[next++] = row; };
  for (std::size_t cell = 0; cell < cells; ++cell) {
    surface_first_[cell] = next;
    visit_rows_within(cell_normal_[cell], kernel_rad, 256, append);
  }
  surface_first_[cells] = next;
  for (std::size_t cell = 0; cell < cells; ++cell) {
    line_first_[cell] = next;
    visit_rows_perpendicular_to(cell_normal_[cell], append);
  }
  line_first_[cells] = next;
}

std::uint32_t OrientationGrid::cell_of(const Eigen::Vector3f& normal) const noexcept {
  // Without data-dependent branches (selects and a floor instead): half the normals are walls
  // on the equator band and half of any set point west, so branches here mispredict.
  const float sign = normal.z() < 0.0f ? -1.0f : 1.0f;
  const Eigen::Vector3f n = normal * sign;
  const float theta = acos_unit(std::min(n.z(), 1.0f));
  // The nearest band (floor is an instruction, lround a libm call).
  const auto band = std::min<std::uint32_t>(
      static_cast<std::uint32_t>(std::floor(theta * inverse_band_step_ + 0.5f)), band_count_ - 1);
  const std::uint32_t cells = band_cells_[band];
  // The turn of phi around the band's circle, in [0, 1): the equator band holds half a circle
  // (n and -n are one plane there), the others a whole one.
  constexpr float kInverseTwoPi = 0.5f / std::numbers::pi_v<float>;
  const float turns_per_rad = band + 1 == band_count_ ? 2.0f * kInverseTwoPi : kInverseTwoPi;
  float turn = fast_atan2(n.y(), n.x()) * turns_per_rad;
  turn -= std::floor(turn);
  const auto j = std::min<std::uint32_t>(
      static_cast<std::uint32_t>(turn * static_cast<float>(cells)), cells - 1);
  return band_first_cell_[band] + j;
}

std::span<const OrientationGrid::Neighbour> OrientationGrid::neighbours(
    std::uint32_t row) const noexcept {
  return {neighbour_table_.data() + static_cast<std::size_t>(row) * kMaxNeighbours,
          neighbour_count_[row]};
}

void OrientationGrid::build_neighbours() {
  // Cells whose centres are within 1.6 cell widths: the ring of (up to) eight around a cell.
  const float radius = 1.6f * band_step_rad_;
  for (std::uint32_t row = 0; row < row_cell_.size(); ++row) {
    const Eigen::Vector3f& n = cell_normal_[row_cell_[row]];
    std::size_t count = 0;
    Neighbour* table = neighbour_table_.data() + static_cast<std::size_t>(row) * kMaxNeighbours;
    visit_rows_within(n, radius, kMaxNeighbours + 1, [&](std::uint32_t other) {
      if (other == row || count == kMaxNeighbours) {
        return;
      }
      table[count++] = Neighbour{other, cell_normal_[row_cell_[other]].dot(n) < 0.0f};
    });
    neighbour_count_[row] = static_cast<std::uint8_t>(count);
  }
}

std::size_t OrientationGrid::memory_bytes() const noexcept {
  return band_first_cell_.size_bytes() + band_cells_.size_bytes() + cell_normal_.size_bytes() +
         cell_row_.size_bytes() + row_cell_.size_bytes() + neighbour_table_.size_bytes() +
         neighbour_count_.size_bytes() + surface_first_.size_bytes() + line_first_.size_bytes() +
         flat_.size_bytes() + searched_height_.size_bytes();
}

}  // namespace blockmap::planes
