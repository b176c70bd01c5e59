#include "blockmap/buildings/block_tracer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "blockmap/core/check.hpp"

namespace blockmap::buildings {
namespace {

// Visited, and not a block (open to the raster's edge, or too small).
constexpr std::uint16_t kNotABlock = std::numeric_limits<std::uint16_t>::max();
constexpr std::size_t kSlack = 64;  // alignment of each array
// Columns are median-filtered over this many (a tree against the block, a few metres wide,
// is not a step of it).
constexpr std::size_t kMedianColumns = 5;
// Two neighbouring bands whose sides are this close after snapping are one band.
constexpr double kSameSideM = 1.0;

std::size_t max_columns(std::size_t max_cells) noexcept {
  // The raster's diagonal in cells, and a column is at least a cell wide.
  return 2 * static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(max_cells)))) + 2;
}

Eigen::Vector2d turned(const Eigen::Vector2d& p, double axis_rad) noexcept {
  const double c = std::cos(axis_rad);
  const double s = std::sin(axis_rad);
  return {c * p.x() + s * p.y(), -s * p.x() + c * p.y()};
}

// The overlap of two intervals (negative when apart).
double overlap(double lo_a, double hi_a, double lo_b, double hi_b) noexcept {
  return std::min(hi_a, hi_b) - std::max(lo_a, lo_b);
}

}  // namespace

void BlockTracer::init(Arena& arena, const BuildingsConfig& config, std::size_t max_cells) {
  config_ = config;
  block_count_ = 0;
  if (max_cells == 0) {
    return;
  }
  labels_ = arena.allocate_array<std::uint16_t>(max_cells, "buildings.blocks");
  cells_ = arena.allocate_array<std::uint32_t>(max_cells, "buildings.blocks");
  blocks_ = arena.allocate_array<Block>(config.max_blocks, "buildings.blocks");
  column_lo_ = arena.allocate_array<double>(max_columns(max_cells), "buildings.blocks");
  column_hi_ = arena.allocate_array<double>(max_columns(max_cells), "buildings.blocks");
  scratch_ = arena.allocate_array<double>(max_columns(max_cells), "buildings.blocks");
}

std::size_t BlockTracer::arena_bytes(const BuildingsConfig& config,
                                     std::size_t max_cells) noexcept {
  if (max_cells == 0) {
    return 0;
  }
  return max_cells * (sizeof(std::uint16_t) + sizeof(std::uint32_t)) +
         config.max_blocks * sizeof(Block) + 3 * max_columns(max_cells) * sizeof(double) +
         6 * kSlack;
}

std::size_t BlockTracer::memory_bytes() const noexcept {
  return labels_.size_bytes() + cells_.size_bytes() + blocks_.size_bytes() +
         column_lo_.size_bytes() + column_hi_.size_bytes() + scratch_.size_bytes();
}

std::span<const BlockTracer::Block> BlockTracer::find_blocks(
    const map::FreeSpaceRaster& raster) noexcept {
  raster_ = raster;
  block_count_ = 0;
  const std::size_t across = raster.cells_across;
  const std::size_t count = across * across;
  if (count == 0 || count > labels_.size() || raster.free.size() < count) {
    return {};
  }
  std::fill_n(labels_.begin(), count, std::uint16_t{0});
  const double cell_area_m2 = raster.cell_size_m * raster.cell_size_m;
  std::uint32_t end = 0;  // cells_[0, end): the blocks kept so far, then the region being grown
  for (std::uint32_t seed = 0; seed < count; ++seed) {
    if (raster.free[seed] != 0 || labels_[seed] != 0) {
      continue;
    }
    // Grow the region of cells not free around the seed, breadth first; cells_ is its queue.
    const auto label = static_cast<std::uint16_t>(block_count_ + 1);
    const std::uint32_t first = end;
    cells_[end++] = seed;
    labels_[seed] = label;
    bool open = false;
    for (std::uint32_t head = first; head < end; ++head) {
      const std::uint32_t cell = cells_[head];
      const std::size_t x = cell % across;
      const std::size_t y = cell / across;
      open = open || x == 0 || y == 0 || x + 1 == across || y + 1 == across;
      const auto visit = [&](std::size_t next) {
        if (raster.free[next] == 0 && labels_[next] == 0) {
          labels_[next] = label;
          cells_[end++] = static_cast<std::uint32_t>(next);
        }
      };
      if (x > 0) visit(cell - 1);
      if (x + 1 < across) visit(cell + 1);
      if (y > 0) visit(cell - across);
      if (y + 1 < across) visit(cell + across);
    }
    const std::uint32_t size = end - first;
    const bool kept = !open &&
                      static_cast<double>(size) * cell_area_m2 >= config_.min_block_area_m2 &&
                      block_count_ < blocks_.size();
    if (kept) {
      blocks_[block_count_++] = {label, first, size};
    } else {
      for (std::uint32_t k = first; k < end; ++k) {
        labels_[cells_[k]] = kNotABlock;
      }
      end = first;
    }
  }
  return blocks_.first(block_count_);
}

Eigen::Vector2d BlockTracer::cell_centre(std::uint32_t cell) const noexcept {
  const std::size_t across = raster_.cells_across;
  const std::size_t row = cell / across;  // whole rows
  return raster_.origin_m +
         raster_.cell_size_m * Eigen::Vector2d(static_cast<double>(cell % across) + 0.5,
                                               static_cast<double>(row) + 0.5);
}

bool BlockTracer::is_free(const Eigen::Vector2d& p_m) const noexcept {
  const Eigen::Vector2d at = (p_m - raster_.origin_m) / raster_.cell_size_m;
  const auto across = static_cast<double>(raster_.cells_across);
  if (!(at.x() >= 0.0 && at.y() >= 0.0 && at.x() < across && at.y() < across)) {
    return false;
  }
  return raster_.free[static_cast<std::size_t>(std::floor(at.y())) * raster_.cells_across +
                      static_cast<std::size_t>(std::floor(at.x()))] != 0;
}

bool BlockTracer::reaches(const Block& block, const Eigen::Vector2d& p_m,
                          double reach_m) const noexcept {
  const auto across = static_cast<std::int64_t>(raster_.cells_across);
  const Eigen::Vector2d at = (p_m - raster_.origin_m) / raster_.cell_size_m;
  const auto radius = static_cast<std::int64_t>(std::ceil(reach_m / raster_.cell_size_m));
  const auto cx = static_cast<std::int64_t>(std::floor(at.x()));
  const auto cy = static_cast<std::int64_t>(std::floor(at.y()));
  const double reach_cells2 = (reach_m / raster_.cell_size_m) * (reach_m / raster_.cell_size_m);
  for (std::int64_t y = std::max<std::int64_t>(0, cy - radius);
       y <= std::min(across - 1, cy + radius); ++y) {
    for (std::int64_t x = std::max<std::int64_t>(0, cx - radius);
         x <= std::min(across - 1, cx + radius); ++x) {
      const double dx = static_cast<double>(x) + 0.5 - at.x();
      const double dy = static_cast<double>(y) + 0.5 - at.y();
      if (dx * dx + dy * dy <= reach_cells2 &&
          labels_[static_cast<std::size_t>(y * across + x)] == block.label) {
        return true;
      }
    }
  }
  return false;
}

std::size_t BlockTracer::measure_columns(const Block& block, double axis_rad,
                                         double& u_start) noexcept {
  const std::span<const std::uint32_t> cells = cells_.subspan(block.first_cell, block.cell_count);
  const double half_cell = 0.5 * raster_.cell_size_m;
  double u_min = std::numeric_limits<double>::infinity();
  double u_max = -u_min;
  for (const std::uint32_t cell : cells) {
    const double u = turned(cell_centre(cell), axis_rad).x();
    u_min = std::min(u_min, u);
    u_max = std::max(u_max, u);
  }
  u_start = u_min - half_cell;
  const std::size_t columns = std::min(
      column_lo_.size(),
      static_cast<std::size_t>((u_max - u_min + 2.0 * half_cell) / config_.block_column_m) + 1);
  std::fill_n(column_lo_.begin(), columns, std::numeric_limits<double>::infinity());
  std::fill_n(column_hi_.begin(), columns, -std::numeric_limits<double>::infinity());
  for (const std::uint32_t cell : cells) {
    const Eigen::Vector2d q = turned(cell_centre(cell), axis_rad);
    const auto k =
        std::min(columns - 1, static_cast<std::size_t>((q.x() - u_start) / config_.block_column_m));
    column_lo_[k] = std::min(column_lo_[k], q.y() - half_cell);
    column_hi_[k] = std::max(column_hi_[k], q.y() + half_cell);
  }
  // A column no cell fell in (the block turned against the raster) takes its neighbour's.
  for (std::size_t k = 1; k < columns; ++k) {
    if (column_lo_[k] > column_hi_[k]) {
      column_lo_[k] = column_lo_[k - 1];
      column_hi_[k] = column_hi_[k - 1];
    }
  }
  for (std::span<double> side : {column_lo_.first(columns), column_hi_.first(columns)}) {
    std::copy(side.begin(), side.end(), scratch_.begin());
    for (std::size_t k = 0; k < columns; ++k) {
      const std::size_t lo = k >= kMedianColumns / 2 ? k - kMedianColumns / 2 : 0;
      const std::size_t hi = std::min(columns, k + kMedianColumns / 2 + 1);
      std::array<double, kMedianColumns> window{};
      std::copy(scratch_.begin() + static_cast<std::ptrdiff_t>(lo),
                scratch_.begin() + static_cast<std::ptrdiff_t>(hi), window.begin());
      const std::size_t n = hi - lo;
      std::nth_element(window.begin(), window.begin() + static_cast<std::ptrdiff_t>(n / 2),
                       window.begin() + static_cast<std::ptrdiff_t>(n));
      side[k] = window[n / 2];
    }
  }
  return columns;
}

void BlockTracer::join_bands(std::size_t a) noexcept {
  // Band a + 1 into band a, their sides length-weighted.
  Band& left = bands_[a];
  const Band& right = bands_[a + 1];
  const double wl = left.u1 - left.u0;
  const double wr = right.u1 - right.u0;
  left.v_lo = (wl * left.v_lo + wr * right.v_lo) / (wl + wr);
  left.v_hi = (wl * left.v_hi + wr * right.v_hi) / (wl + wr);
  left.u1 = right.u1;
  std::copy(bands_.begin() + static_cast<std::ptrdiff_t>(a + 2),
            bands_.begin() + static_cast<std::ptrdiff_t>(band_count_),
            bands_.begin() + static_cast<std::ptrdiff_t>(a + 1));
  --band_count_;
}

std::size_t BlockTracer::cut_bands(std::size_t columns, double u_start) noexcept {
  const double column_m = config_.block_column_m;
  band_count_ = 0;
  // Greedy: a column whose extent across differs from its band's mean by more than a step
  // starts a new band.
  double sum_lo = 0.0;
  double sum_hi = 0.0;
  std::size_t in_band = 0;
  std::size_t band_first = 0;
  const auto close_band = [&](std::size_t end_column) {
    const auto n = static_cast<double>(in_band);
    bands_[band_count_++] = {u_start + static_cast<double>(band_first) * column_m,
                             u_start + static_cast<double>(end_column) * column_m, sum_lo / n,
                             sum_hi / n};
  };
  for (std::size_t k = 0; k < columns; ++k) {
    const auto n = static_cast<double>(in_band);
    const bool step = in_band > 0 && (std::abs(column_lo_[k] - sum_lo / n) > config_.block_step_m ||
                                      std::abs(column_hi_[k] - sum_hi / n) > config_.block_step_m);
    if (step && band_count_ + 1 < bands_.size()) {
      close_band(k);
      sum_lo = sum_hi = 0.0;
      in_band = 0;
      band_first = k;
    }
    sum_lo += column_lo_[k];
    sum_hi += column_hi_[k];
    ++in_band;
  }
  close_band(columns);
  // Bands narrower than block_min_band_m, and then the most alike neighbours while there are
  // more than kMaxBands, join the neighbour nearest in extent (length-weighted).
  const auto difference = [&](std::size_t a) {  // between band a and band a + 1
    return std::abs(bands_[a].v_lo - bands_[a + 1].v_lo) +
           std::abs(bands_[a].v_hi - bands_[a + 1].v_hi);
  };
  for (bool joined = true; joined && band_count_ > 1;) {
    joined = false;
    std::size_t narrowest = 0;
    for (std::size_t b = 1; b < band_count_; ++b) {
      if (bands_[b].u1 - bands_[b].u0 < bands_[narrowest].u1 - bands_[narrowest].u0) {
        narrowest = b;
      }
    }
    const double width = bands_[narrowest].u1 - bands_[narrowest].u0;
    if (width < config_.block_min_band_m || band_count_ > kMaxBands) {
      const bool with_left = narrowest + 1 == band_count_ ||
                             (narrowest > 0 && difference(narrowest - 1) <= difference(narrowest));
      join_bands(with_left ? narrowest - 1 : narrowest);
      joined = true;
    }
  }
  return band_count_;
}

void BlockTracer::snap_to_walls(std::span<const SideWall> walls) noexcept {
  const double snap_m = config_.block_snap_m;
  // The overlap-weighted level of the walls along `axis` within snap_m of `level` that
  // overlap [lo, hi]; `level` when none does.
  const auto wall_level = [&](int axis, double level, double lo, double hi) {
    double weighted = 0.0;
    double weight = 0.0;
    for (const SideWall& wall : walls) {
      const double shared = overlap(wall.lo, wall.hi, lo, hi);
      if (wall.axis == axis && std::abs(wall.level - level) <= snap_m && shared > 0.0) {
        weighted += shared * wall.level;
        weight += shared;
      }
    }
    return weight > 0.0 ? weighted / weight : level;
  };
  for (std::size_t b = 0; b < band_count_; ++b) {
    Band& band = bands_[b];
    band.v_lo = wall_level(0, band.v_lo, band.u0, band.u1);
    band.v_hi = wall_level(0, band.v_hi, band.u0, band.u1);
  }
  // The ends, and each step between two bands: a wall across the outline where one band's
  // side steps to the other's (on top, at the bottom, or both).
  bands_[0].u0 = wall_level(1, bands_[0].u0, bands_[0].v_lo, bands_[0].v_hi);
  Band& last = bands_[band_count_ - 1];
  last.u1 = wall_level(1, last.u1, last.v_lo, last.v_hi);
  for (std::size_t b = 0; b + 1 < band_count_; ++b) {
    Band& left = bands_[b];
    Band& right = bands_[b + 1];
    double u =
        wall_level(1, left.u1, std::min(left.v_hi, right.v_hi), std::max(left.v_hi, right.v_hi));
    if (u == left.u1) {  // no wall at the top's step (the level comes back as it was)
      u = wall_level(1, left.u1, std::min(left.v_lo, right.v_lo), std::max(left.v_lo, right.v_lo));
    }
    if (u > left.u0 && u < right.u1) {
      left.u1 = u;
      right.u0 = u;
    }
  }
}

double BlockTracer::long_axis(const Block& block, double axis_rad) const noexcept {
  Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d high = -low;
  for (const std::uint32_t cell : cells_.subspan(block.first_cell, block.cell_count)) {
    const Eigen::Vector2d q = turned(cell_centre(cell), axis_rad);
    low = low.cwiseMin(q);
    high = high.cwiseMax(q);
  }
  return high.y() - low.y() > high.x() - low.x() ? axis_rad + 0.5 * std::numbers::pi : axis_rad;
}

namespace {

// Drops the corners of a ring of n that repeat their predecessor or lie in line with both
// neighbours, keeping four at least; returns how many are left.
template <std::size_t N>
std::size_t drop_corners_in_line(std::array<Eigen::Vector2d, N>& ring, std::size_t n) {
  for (bool dropped = true; dropped && n > 4;) {
    dropped = false;
    for (std::size_t k = 0; k < n && n > 4; ++k) {
      const Eigen::Vector2d& prev = ring[(k + n - 1) % n];
      const Eigen::Vector2d& here = ring[k];
      const Eigen::Vector2d& next = ring[(k + 1) % n];
      const bool repeated = (here - prev).norm() < 1e-9;
      const bool in_line =
          (std::abs(prev.x() - here.x()) < 1e-9 && std::abs(here.x() - next.x()) < 1e-9) ||
          (std::abs(prev.y() - here.y()) < 1e-9 && std::abs(here.y() - next.y()) < 1e-9);
      if (repeated || in_line) {
        std::copy(ring.begin() + static_cast<std::ptrdiff_t>(k + 1),
                  ring.begin() + static_cast<std::ptrdiff_t>(n),
                  ring.begin() + static_cast<std::ptrdiff_t>(k));
        --n;
        dropped = true;
      }
    }
  }
  return n;
}

}  // namespace

BlockTracer::Outline BlockTracer::outline(const Block& block, double axis_rad,
                                          std::span<const SideWall> walls) noexcept {
  Outline out;
  if (block.cell_count == 0 || column_lo_.empty()) {
    return out;
  }
  double u_start = 0.0;
  const std::size_t columns = measure_columns(block, axis_rad, u_start);
  if (cut_bands(columns, u_start) == 0) {
    return out;
  }
  snap_to_walls(walls);
  merge_alike_bands();
  // Counter-clockwise (u right, v up): along the bottom from the west, up the east end, back
  // along the top; then corners in line with their neighbours are dropped.
  std::array<Eigen::Vector2d, 4 * kMaxBands> ring{};
  std::size_t n = 0;
  for (std::size_t b = 0; b < band_count_; ++b) {
    ring[n++] = {bands_[b].u0, bands_[b].v_lo};
    ring[n++] = {bands_[b].u1, bands_[b].v_lo};
  }
  for (std::size_t b = band_count_; b-- > 0;) {
    ring[n++] = {bands_[b].u1, bands_[b].v_hi};
    ring[n++] = {bands_[b].u0, bands_[b].v_hi};
  }
  n = drop_corners_in_line(ring, n);
  std::copy_n(ring.begin(), n, out.corners.begin());
  out.size = static_cast<std::uint8_t>(n);
  return out;
}

void BlockTracer::merge_alike_bands() noexcept {
  // Sides of neighbouring bands that landed within kSameSideM of each other are one side (a
  // jog that small is two walls' fits, not a step of the block); bands alike on both are one.
  for (std::size_t b = 0; b + 1 < band_count_; ++b) {
    Band& left = bands_[b];
    Band& right = bands_[b + 1];
    const double wl = left.u1 - left.u0;
    const double wr = right.u1 - right.u0;
    for (double Band::*side : {&Band::v_lo, &Band::v_hi}) {
      if (std::abs(left.*side - right.*side) < kSameSideM) {
        left.*side = right.*side = (wl * left.*side + wr * right.*side) / (wl + wr);
      }
    }
  }
  // Bands whose sides landed on the same walls are one.
  for (std::size_t b = 0; b + 1 < band_count_;) {
    if (std::abs(bands_[b].v_lo - bands_[b + 1].v_lo) < kSameSideM &&
        std::abs(bands_[b].v_hi - bands_[b + 1].v_hi) < kSameSideM) {
      join_bands(b);
    } else {
      ++b;
    }
  }
}

}  // namespace blockmap::buildings
