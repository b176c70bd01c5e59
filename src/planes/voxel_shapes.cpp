// VoxelGrid::estimate_shapes(): each sample's local shape from its 3 x 3 x 3 neighbourhood,
// the coarse second look at the blocks around it, and which kept shapes must be estimated again.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>

#include <Eigen/Geometry>

#include "blockmap/core/check.hpp"
#include "blockmap/planes/fast_trig.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::planes {

CentredSums VoxelGrid::sum_block(std::uint32_t block) const noexcept {
  CentredSums sums;
  const BlockRange range = block_range(block);
  for (std::uint32_t id = range.first; id < range.first + range.count; ++id) {
    sums.add(centred_sums_[id]);
  }
  return sums;
}

namespace {

// The cells of a block next to its neighbour in direction (dx, dy, dz) (each -1, 0 or 1): the
// ones whose 3 x 3 x 3 neighbourhood reaches into that neighbour.
constexpr std::uint64_t cells_facing(int dx, int dy, int dz) noexcept {
  std::uint64_t mask = 0;
  for (int x = 0; x < 4; ++x) {
    for (int y = 0; y < 4; ++y) {
      for (int z = 0; z < 4; ++z) {
        const bool faces = (dx == 0 || x == (dx < 0 ? 0 : 3)) &&
                           (dy == 0 || y == (dy < 0 ? 0 : 3)) && (dz == 0 || z == (dz < 0 ? 0 : 3));
        if (faces) {
          mask |= std::uint64_t{1} << ((x << 4) | (y << 2) | z);
        }
      }
    }
  }
  return mask;
}

// The index of a block's own entry among the 27 of its neighbourhood (offset 0, 0, 0).
constexpr std::size_t kOwnBlock = 13;

constexpr std::array<std::uint64_t, 27> kCellsFacing = [] {
  std::array<std::uint64_t, 27> masks{};
  std::size_t k = 0;
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz) {
        masks[k++] = cells_facing(dx, dy, dz);
      }
    }
  }
  return masks;
}();

}  // namespace

void VoxelGrid::load_neighbourhood(std::int64_t bx, std::int64_t by, std::int64_t bz,
                                   std::uint64_t live, BlockNeighbourhood& out) const noexcept {
  // Most blocks hold a few samples on one surface: only the neighbours that their cells touch
  // are looked up.
  std::size_t k = 0;
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz, ++k) {
        out.live_masks[k] = 0;
        out.first[k] = 0;
        out.changed[k] = 0;
        if ((live & kCellsFacing[k]) == 0) {
          continue;
        }
        const std::uint32_t block = block_index_.find(pack_cell(bx + dx, by + dy, bz + dz));
        if (block != CellIndex::kAbsent) {
          out.live_masks[k] = live_masks_[block];
          out.first[k] = block_first_[block];
          out.changed[k] = keeping_shapes_ ? changed_cells_[block] : 0;
          // The shape pass reads these sums a block or two later.
          __builtin_prefetch(&centred_sums_[block_first_[block]]);
        }
      }
    }
  }
}

void VoxelGrid::estimate_shapes(const ShapeOptions& options,
                                std::span<std::uint32_t> voting_points) noexcept {
  BLOCKMAP_CHECK_MSG(voting_points.empty() || voting_points.size() >= block_count_,
                     "voting points need an entry per block");
  const auto squared = [](double ratio) { return static_cast<float>(ratio * ratio); };
  ShapeLimits limits;
  limits.planar_ratio_sq = squared(options.max_planarity_ratio);
  limits.line_ratio_sq = squared(options.max_line_ratio);
  limits.min_points = static_cast<float>(options.min_points);
  limits.level_slices = options.level_slices;
  double thickness_sum_m = 0.0;
  std::uint64_t planar_count = 0;
  shape_tally_ = ShapeTally{};
  // Erased blocks keep their index and hold no samples: no points.
  std::fill_n(voting_points.begin(), voting_points.empty() ? 0 : block_count_, 0U);
  estimate_fine_shapes(limits, options.every_sample_votes, voting_points, thickness_sum_m,
                       planar_count);
  surface_noise_m_ = planar_count > 0 ? thickness_sum_m / static_cast<double>(planar_count) : 0.0;
  shape_tally_.planar = planar_count;
  // Level slices have no second look: at 2.4 m they are flat too, and only the slice.
  if (options.coarse_second_look && !options.level_slices) {
    take_coarse_look(options, limits, voting_points);
  }
  if (keeping_shapes_) {
    // Changed and stale are done with; placed stays until the index serves a new key, and
    // what the samples went through is what samples_changed() tells till the next pass.
    for (std::size_t block = 0; block < block_count_; ++block) {
      const std::uint8_t flags = block_flags_[block];
      const bool samples_changed = (flags & (kChanged | kLoaded | kReshaped)) != 0;
      block_flags_[block] = static_cast<std::uint8_t>((flags & (kPlaced | kCoarseApplied)) |
                                                      (samples_changed ? kSamplesChanged : 0));
      changed_cells_[block] = 0;
    }
  }
}

void VoxelGrid::take_coarse_look(const ShapeOptions& options, ShapeLimits limits,
                                 std::span<std::uint32_t> voting_points) noexcept {
  const auto squared = [](double ratio) { return static_cast<float>(ratio * ratio); };
  // The second look knows how thick this cloud's surfaces are: a slab a few surface-noise
  // thicknesses thick is a blurred wall (pose errors blur every surface alike), where a crisp
  // cloud's slab of that thickness is a hedge or a row of bushes.
  limits.noisy_slab_ratio_sq = squared(options.max_noisy_slab_ratio);
  limits.noisy_slab_thickness_m2 = squared(options.noisy_slab_per_noise * surface_noise_m_);
  for (std::size_t i = 0; i < block_count_; ++i) {
    const std::uint32_t block = block_order_[i].block;
    const BlockRange range = block_range(block);
    const std::span<Voxel> samples = voxels_.subspan(range.first, range.count);
    const auto scattered = [](const Voxel& v) { return v.shape == LocalShape::kScattered; };
    const Eigen::Vector3f normal = (block_summed_[block] & kHoldsScattered) == 0
                                       ? Eigen::Vector3f::Zero()
                                       : coarse_normal(block, limits);
    if (keeping_shapes_) {
      note_coarse_look(block, !normal.isZero());
    }
    if (normal.isZero()) {
      continue;
    }
    for (Voxel& voxel : samples) {
      if (scattered(voxel)) {
        voxel.shape = LocalShape::kPlanar;
        voxel.axis = normal;
        voxel.coarse_look = true;
        --shape_tally_.scattered;
        ++shape_tally_.planar;
        if (!voting_points.empty() && !options.every_sample_votes) {
          voting_points[block] += voxel.point_count;  // planar now: it votes
        }
      }
    }
  }
}

void VoxelGrid::note_coarse_look(std::uint32_t block, bool applied) noexcept {
  // Applied now and not before, or the other way round: the block's scattered samples changed.
  // (When it was applied both times, a moved normal was noted where it was estimated again.)
  const bool before = (block_flags_[block] & kCoarseApplied) != 0;
  if (applied != before) {
    block_flags_[block] |= kReshaped;
  }
  block_flags_[block] = static_cast<std::uint8_t>(
      applied ? (block_flags_[block] | kCoarseApplied) : (block_flags_[block] & ~kCoarseApplied));
}

void VoxelGrid::mark_stale_around(CellKey block_key, std::uint8_t flags) noexcept {
  const auto b = unpack_cell(block_key);
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const std::uint32_t near = block_index_.find(pack_cell(b.x() + dx, b.y() + dy, b.z() + dz));
        if (near != CellIndex::kAbsent) {
          block_flags_[near] |= flags;
        }
      }
    }
  }
}

namespace {

// A block's cells as a 64-bit mask, bit = x * 16 + y * 4 + z (bit_in_block): the cells at
// local coordinate 0 and 3 of each axis, and the bit distance of one step along it.
struct CellAxis {
  std::uint64_t low;   // coordinate 0
  std::uint64_t high;  // coordinate 3
  std::uint32_t step;
};
constexpr std::array<CellAxis, 3> kCellAxes{{{0x000000000000FFFFULL, 0xFFFF000000000000ULL, 16},
                                             {0x000F000F000F000FULL, 0xF000F000F000F000ULL, 4},
                                             {0x1111111111111111ULL, 0x8888888888888888ULL, 1}}};

// The cells within one step of `cells` along an axis, inside the block.
std::uint64_t dilated(std::uint64_t cells, const CellAxis& axis) noexcept {
  return cells | ((cells << axis.step) & ~axis.low) | ((cells >> axis.step) & ~axis.high);
}

}  // namespace

std::uint64_t VoxelGrid::stale_cells(const BlockNeighbourhood& around) noexcept {
  // A fine shape reads the 3 x 3 x 3 cells around its own: a cell is stale when a changed
  // cell lies among those, in this block or, at its faces, edges and corners, in the blocks
  // beside it. Per neighbouring block: its changed cells on this side, moved across
  // (coordinate 3 to 0 or 0 to 3), then spread one step along the axes the offset keeps.
  // (Neighbours that no live cell here faces were not looked up: their changes reach no
  // sample of this block.)
  std::uint64_t stale = 0;
  std::size_t k = 0;
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz, ++k) {
        const std::array<int, 3> offset{dx, dy, dz};
        std::uint64_t cells = around.changed[k];
        for (std::size_t a = 0; a < 3 && cells != 0; ++a) {
          const CellAxis& axis = kCellAxes[a];
          const std::uint32_t across = 3 * axis.step;
          if (offset[a] < 0) {
            cells = (cells & axis.high) >> across;
          } else if (offset[a] > 0) {
            cells = (cells & axis.low) << across;
          } else {
            cells = dilated(cells, axis);
          }
        }
        stale |= cells;
      }
    }
  }
  return stale;
}

void VoxelGrid::mark_stale_blocks() noexcept {
  for (std::size_t block = 0; block < block_count_; ++block) {
    if ((block_flags_[block] & kChanged) == 0) {
      continue;
    }
    // The blocks around may hold stale cells, and their coarse spreads read this block.
    mark_stale_around(block_keys_[block], kStale);
  }
}

// One function, longer than most: the pipelined walk over every block, whose look-ahead ring
// and per-block sums its steps share (the shape pass's hottest loop).
void VoxelGrid::estimate_fine_shapes(const ShapeLimits& limits, bool every_sample_votes,
                                     std::span<std::uint32_t> voting_points,
                                     double& thickness_sum_m,
                                     std::uint64_t& planar_count) noexcept {
  shapes_reused_ = 0;
  if (keeping_shapes_) {
    mark_stale_blocks();
  }
  // Blocks that may hold stale cells (all of them without kept shapes): their neighbourhood
  // is looked up, and tells which cells are stale.
  const auto may_be_stale = [this](std::size_t i) {
    return !keeping_shapes_ || (block_flags_[block_order_[i].block] & (kStale | kAllStale)) != 0;
  };
  // Pipelined: the neighbourhood of the block kAhead places on is looked up (and its sums
  // fetched) while this block's samples are summed. A block whose shapes are kept needs none.
  constexpr std::size_t kAhead = 2;
  std::array<BlockNeighbourhood, kAhead + 1> ring;
  const auto look_up = [&](std::size_t i) {
    if (!may_be_stale(i)) {
      return;
    }
    const std::uint32_t block = block_order_[i].block;
    const auto b = unpack_cell(block_keys_[block]);
    load_neighbourhood(b.x(), b.y(), b.z(), live_masks_[block], ring[i % ring.size()]);
  };
  // The cells of block i whose fine shapes are estimated again.
  const auto stale_in = [&](std::size_t i) {
    const std::uint32_t block = block_order_[i].block;
    if (!may_be_stale(i)) {
      return std::uint64_t{0};
    }
    if (!keeping_shapes_ || (block_flags_[block] & kAllStale) != 0) {
      return ~std::uint64_t{0};
    }
    return stale_cells(ring[i % ring.size()]);
  };
  for (std::size_t i = 0; i < std::min(kAhead, block_count_); ++i) {
    look_up(i);
  }
  for (std::size_t i = 0; i < block_count_; ++i) {
    if (i + kAhead < block_count_) {
      look_up(i + kAhead);
    }
    const std::uint32_t block = block_order_[i].block;
    const BlockRange range = block_range(block);
    const BlockNeighbourhood& around = ring[i % ring.size()];
    const std::uint64_t stale = stale_in(i);
    // Samples read from the table have lost their shapes; moved ones carry them.
    const bool loaded = keeping_shapes_ && (block_flags_[block] & kLoaded) != 0;
    if (keeping_shapes_ && (stale & live_masks_[block]) != 0) {
      block_flags_[block] |= kReshaped;
    }
    // The block's samples are its live cells in bit order.
    std::uint64_t cells = live_masks_[block];
    float thickness_sum = 0.0f;  // per block in float, over the cloud in double
    std::uint32_t block_voting_points = 0;
    std::uint32_t block_scattered = 0;
    for (std::uint32_t id = range.first; id < range.first + range.count; ++id, cells &= cells - 1) {
      Voxel& voxel = voxels_[id];
      if ((stale & cells & (~cells + 1)) != 0) {
        voxel.fine_thickness_m = estimate_shape(voxel, around, limits);
        if (keeping_shapes_) {
          kept_[dense_serial_[id]] =
              KeptShape{voxel.axis, voxel.fine_thickness_m, voxel.shape, true};
        }
      } else {
        ++shapes_reused_;
        if (loaded) {
          // A new sample marks its cell changed, so a kept shape was estimated before.
          const KeptShape& kept = kept_[dense_serial_[id]];
          BLOCKMAP_CHECK_MSG(kept.valid, "a kept block holds a sample never estimated");
          voxel.shape = kept.shape;
          voxel.axis = kept.axis;
          voxel.fine_thickness_m = kept.thickness_m;
        } else if (voxel.coarse_look) {
          // What the coarse look made planar was scattered (it looks again below).
          voxel.shape = LocalShape::kScattered;
          voxel.axis = Eigen::Vector3f::UnitZ();
        }
      }
      voxel.coarse_look = false;
      // What the last detection left in the sample.
      voxel.owner = -1;
      voxel.axis_cell = kAxisCellUnknown;
      const float thickness_m = voxel.fine_thickness_m;
      const bool planar = voxel.shape == LocalShape::kPlanar;
      const bool linear = voxel.shape == LocalShape::kLinear;
      if (planar) {
        thickness_sum += thickness_m;
        ++planar_count;
      }
      block_scattered += voxel.shape == LocalShape::kScattered ? 1 : 0;
      shape_tally_.linear += linear ? 1 : 0;
      block_voting_points += every_sample_votes || planar || linear ? voxel.point_count : 0;
    }
    thickness_sum_m += static_cast<double>(thickness_sum);
    shape_tally_.scattered += block_scattered;
    block_summed_[block] = static_cast<std::uint8_t>((block_summed_[block] & ~kHoldsScattered) |
                                                     (block_scattered > 0 ? kHoldsScattered : 0));
    if (!voting_points.empty()) {
      voting_points[block] = block_voting_points;
    }
  }
}

namespace {

// Cells of a block by a 4-bit set of local coordinates along one axis (bit = x*16 + y*4 + z):
// `first` is the mask of the cells with coordinate 0 on that axis, `step` the bit distance
// between coordinates.
constexpr std::array<std::uint64_t, 16> cells_with(std::uint64_t first, std::uint32_t step) {
  std::array<std::uint64_t, 16> masks{};
  for (std::uint32_t set = 0; set < 16; ++set) {
    for (std::uint32_t c = 0; c < 4; ++c) {
      masks[set] |= ((set >> c) & 1U) != 0 ? first << (c * step) : 0;
    }
  }
  return masks;
}
constexpr std::array<std::uint64_t, 16> kCellsWithX = cells_with(0xFFFF, 16);
constexpr std::array<std::uint64_t, 16> kCellsWithY = cells_with(0x000F000F000F000F, 4);
constexpr std::array<std::uint64_t, 16> kCellsWithZ = cells_with(0x1111111111111111, 1);

// Along one axis, the cells within one of local coordinate `local` (0..3): in this block,
// and in the previous or next block when `local` is at a border.
struct AxisSpan {
  int block_offset = 0;      // -1, 0 or 1
  std::uint32_t locals = 0;  // 4-bit set of local coordinates in that block
};
std::size_t axis_spans(std::int64_t local, std::array<AxisSpan, 2>& out) noexcept {
  std::size_t count = 0;
  if (local == 0) {
    out[count++] = {-1, 0b1000U};
  }
  const std::int64_t low = std::max<std::int64_t>(local - 1, 0);
  const std::int64_t high = std::min<std::int64_t>(local + 1, 3);
  out[count++] = {0, ((2U << high) - 1U) & ~((1U << low) - 1U)};
  if (local == 3) {
    out[count++] = {1, 0b0001U};
  }
  return count;
}

// The eigenvalues of a symmetric 3 x 3 matrix, ascending, in closed form (the trigonometric
// solution of its characteristic cubic) and in float with polynomial trigonometry: the shape
// pass needs them for every sample (libm's acos and cos were a twentieth of the detection),
// and one eigenvector only when the shape is planar or linear. The ratio tests compare
// eigenvalues a factor of ten or more apart; float keeps them to a part in a million.
Eigen::Vector3f symmetric_eigenvalues(const Eigen::Matrix3f& a) noexcept {
  const float q = a.trace() / 3.0f;
  const float off = a(0, 1) * a(0, 1) + a(0, 2) * a(0, 2) + a(1, 2) * a(1, 2);
  const Eigen::Matrix3f shifted = a - q * Eigen::Matrix3f::Identity();
  const float p2 = (shifted.diagonal().squaredNorm() + 2.0f * off) / 6.0f;
  if (p2 <= 0.0f) {
    return Eigen::Vector3f::Constant(q);  // a multiple of the identity
  }
  const float p = std::sqrt(p2);
  const float r = std::clamp(shifted.determinant() / (2.0f * p2 * p), -1.0f, 1.0f);
  const float third = acos_signed(r) / 3.0f;  // in [0, pi/3]
  const float c = cos_small(third);
  const float s = sin_small(third);
  constexpr float kHalfSqrt3 = 0.8660254038f;
  const float largest = q + 2.0f * p * c;
  // cos(third + 2 pi / 3) = -cos(third) / 2 - sin(third) sqrt(3) / 2
  const float smallest = q - p * (c + 2.0f * kHalfSqrt3 * s);
  return {smallest, 3.0f * q - largest - smallest, largest};
}

// The unit eigenvector of symmetric `a` for `eigenvalue`, when that eigenvalue is well apart
// from the other two (the callers' ratio tests make sure): the rows of a - eigenvalue I span
// the plane perpendicular to it, so the largest cross product of two rows is the best
// conditioned estimate.
Eigen::Vector3f eigenvector_of(const Eigen::Matrix3f& a, float eigenvalue) noexcept {
  const Eigen::Matrix3f m = a - eigenvalue * Eigen::Matrix3f::Identity();
  const Eigen::Vector3f c01 = m.row(0).cross(m.row(1));
  const Eigen::Vector3f c02 = m.row(0).cross(m.row(2));
  const Eigen::Vector3f c12 = m.row(1).cross(m.row(2));
  const float n01 = c01.squaredNorm();
  const float n02 = c02.squaredNorm();
  const float n12 = c12.squaredNorm();
  const Eigen::Vector3f& best = n01 >= n02 ? (n01 >= n12 ? c01 : c12) : (n02 >= n12 ? c02 : c12);
  const float norm = best.norm();
  return norm > 0.0f ? Eigen::Vector3f(best / norm) : Eigen::Vector3f::UnitZ();
}

// The covariance of the points that `sums` add up, and its eigenvalues (ascending, >= 0).
struct Spread {
  Eigen::Matrix3f covariance;
  Eigen::Vector3f eigenvalues_m2;
};
[[gnu::always_inline]] inline Spread spread_of(const CentredSums& sums) noexcept {
  const std::array<float, 12>& v = sums.values;
  const float inverse_count = 1.0f / v[0];
  const Eigen::Vector3f mean = Eigen::Vector3f(v[1], v[2], v[3]) * inverse_count;
  Eigen::Matrix3f outer;
  outer << v[4], v[5], v[6], v[5], v[7], v[8], v[6], v[8], v[9];
  Spread spread;
  spread.covariance = outer * inverse_count - mean * mean.transpose();
  spread.eigenvalues_m2 = symmetric_eigenvalues(spread.covariance).cwiseMax(0.0f);
  return spread;
}

}  // namespace

VoxelGrid::CoarseSpread VoxelGrid::coarse_spread(std::int64_t bx, std::int64_t by, std::int64_t bz,
                                                 const ShapeLimits* limits) noexcept {
  CentredSums around;
  const float block_m = size_m_ * static_cast<float>(kBlockEdge);
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const std::uint32_t block = block_index_.find(pack_cell(bx + dx, by + dy, bz + dz));
        if (block == CellIndex::kAbsent) {
          continue;
        }
        if ((block_summed_[block] & kSummed) == 0) {
          block_sums_[block] = sum_block(block);
          block_summed_[block] |= kSummed;
        }
        around.add(block_sums_[block].moved_by({static_cast<float>(dx) * block_m,
                                                static_cast<float>(dy) * block_m,
                                                static_cast<float>(dz) * block_m}));
      }
    }
  }
  CoarseSpread out;
  out.point_count = around.values[0];
  if (limits != nullptr && around.values[0] < limits->min_points) {
    return out;
  }
  const Spread spread = spread_of(around);
  out.thickness_m2 = spread.eigenvalues_m2(0);
  out.width_m2 = spread.eigenvalues_m2(1);
  // The eigenvector only when some limits could take it (without limits: always, to keep).
  if (limits == nullptr || coarse_normal_of(out, *limits, true)) {
    out.normal = eigenvector_of(spread.covariance, out.thickness_m2);
  }
  return out;
}

bool VoxelGrid::coarse_normal_of(const CoarseSpread& spread, const ShapeLimits& limits,
                                 bool ignoring_normal) noexcept {
  if (spread.point_count < limits.min_points) {
    return false;
  }
  const float l0 = spread.thickness_m2;
  const float l1 = spread.width_m2;
  const bool planar = l0 <= limits.planar_ratio_sq * l1;
  const bool noisy_slab =
      l0 <= limits.noisy_slab_ratio_sq * l1 && l0 <= limits.noisy_slab_thickness_m2;
  if (!planar && !noisy_slab) {
    return false;
  }
  // A noisy slab is a wall only: a level laser's returns on everything it crosses (walls,
  // cars, bushes) lie in a horizontal sheet as thick as its pitch noise, a false floor.
  constexpr float kMaxSlabNormalZ = 0.5f;  // the normal at least 30 deg off vertical
  return planar || ignoring_normal || std::abs(spread.normal.z()) <= kMaxSlabNormalZ;
}

Eigen::Vector3f VoxelGrid::coarse_normal(std::uint32_t block, const ShapeLimits& limits) noexcept {
  const auto b = unpack_cell(block_keys_[block]);
  if (!keeping_shapes_) {
    const CoarseSpread spread = coarse_spread(b.x(), b.y(), b.z(), &limits);
    return coarse_normal_of(spread, limits, false) ? spread.normal : Eigen::Vector3f::Zero();
  }
  // Kept: the spread of the blocks around changes only when one of them did (a stale block);
  // the limits follow the cloud's surface noise, so they are applied anew.
  CoarseSpread& kept = kept_coarse_[block];
  if (!kept.known || (block_flags_[block] & kStale) != 0) {
    const Eigen::Vector3f normal_before = kept.normal;
    const bool known_before = kept.known;
    kept = coarse_spread(b.x(), b.y(), b.z(), nullptr);
    kept.known = true;
    if (!known_before || kept.normal != normal_before) {
      block_flags_[block] |= kReshaped;  // what the coarse look gives may have moved
    }
  }
  return coarse_normal_of(kept, limits, false) ? kept.normal : Eigen::Vector3f::Zero();
}

// One function, longer than most: run for every sample, the neighbourhood's sums and the
// eigen-decomposition read as one computation.
float VoxelGrid::estimate_shape(Voxel& voxel, const BlockNeighbourhood& around,
                                const ShapeLimits& limits) const noexcept {
  const auto cell = unpack_cell(voxel.key);
  std::array<AxisSpan, 2> xs;
  std::array<AxisSpan, 2> ys;
  std::array<AxisSpan, 2> zs;
  const std::size_t nx = axis_spans(cell.x() & 3, xs);
  const std::size_t ny = axis_spans(cell.y() & 3, ys);
  const std::size_t nz = axis_spans(cell.z() & 3, zs);
  // The neighbourhood's moments about this block's centre, summed over the occupied cells
  // only: the set bits of each neighbouring block's live mask inside the 3 x 3 x 3 box
  // (testing all 27 cells mispredicted a branch on every other one). A neighbouring block's
  // cells are summed about its own centre first and moved once.
  const float block_m = size_m_ * static_cast<float>(kBlockEdge);
  CentredSums total;
  for (std::size_t i = 0; i < nx; ++i) {
    for (std::size_t j = 0; j < ny; ++j) {
      for (std::size_t k = 0; k < nz; ++k) {
        const int which_signed =
            (xs[i].block_offset + 1) * 9 + (ys[j].block_offset + 1) * 3 + zs[k].block_offset + 1;
        const auto which = static_cast<std::size_t>(which_signed);
        const std::uint64_t live = around.live_masks[which];
        std::uint64_t cells = live & kCellsWithX[xs[i].locals] & kCellsWithY[ys[j].locals] &
                              kCellsWithZ[zs[k].locals];
        if (cells == 0) {
          continue;
        }
        CentredSums part;
        for (; cells != 0; cells &= cells - 1) {
          const auto bit = static_cast<std::uint32_t>(std::countr_zero(cells));
          // The cell's id: its block's first id plus the live cells before it in bit order.
          part.add(
              centred_sums_[around.first[which] + static_cast<std::uint32_t>(std::popcount(
                                                      live & ((std::uint64_t{1} << bit) - 1)))]);
        }
        if (which == kOwnBlock) {
          total.add(part);
        } else {
          total.add(part.moved_by({static_cast<float>(xs[i].block_offset) * block_m,
                                   static_cast<float>(ys[j].block_offset) * block_m,
                                   static_cast<float>(zs[k].block_offset) * block_m}));
        }
      }
    }
  }
  // A shape without an axis gets the axis of a sample laid out afresh: compact() moves
  // unchanged blocks' samples with what the last estimate left in them.
  if (total.values[0] < limits.min_points) {
    voxel.shape = LocalShape::kTooFewPoints;
    voxel.axis = Eigen::Vector3f::UnitZ();
    return 0.0f;
  }
  const Spread spread = spread_of(total);
  const Eigen::Vector3f& l = spread.eigenvalues_m2;
  float thickness_m = 0.0f;
  if (l(1) <= limits.line_ratio_sq * l(2)) {
    // Thin in two directions: points along one line (a scan line on a far surface).
    voxel.shape = LocalShape::kLinear;
    voxel.axis = eigenvector_of(spread.covariance, l(2));
  } else if (l(0) <= limits.planar_ratio_sq * l(1)) {
    // Wide in two directions, thin in the third: a surface.
    voxel.shape = LocalShape::kPlanar;
    voxel.axis = eigenvector_of(spread.covariance, l(0));
    thickness_m = std::sqrt(l(0));
    // Within 10 deg of vertical: flat only because a level laser's slice holds its points.
    // Its shape within the slice decides: at most half as wide across as along, the trace of
    // a wall (a trunk's or a bush's is round).
    constexpr float kCosLevelSlice = 0.985F;
    constexpr float kTraceRatioSq = 0.25F;
    if (limits.level_slices && std::abs(voxel.axis.z()) >= kCosLevelSlice) {
      const bool trace = l(1) <= kTraceRatioSq * l(2);
      voxel.shape = trace ? LocalShape::kLinear : LocalShape::kScattered;
      voxel.axis = eigenvector_of(spread.covariance, l(2));
    }
  } else {
    voxel.shape = LocalShape::kScattered;
    voxel.axis = Eigen::Vector3f::UnitZ();
  }
  return thickness_m;
}

}  // namespace blockmap::planes
