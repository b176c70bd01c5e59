#include "blockmap/planes/voxel_grid.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "blockmap/core/check.hpp"

namespace blockmap::planes {

// ---- CellIndex ----

void CellIndex::init(Arena& arena, std::size_t max_keys, const char* owner) {
  BLOCKMAP_CHECK_MSG(max_keys > 0, "cell index needs a capacity");
  // At most half full: short probe sequences.
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(2 * max_keys, 64));
  shift_ = 64u - static_cast<std::uint32_t>(std::countr_zero(slots));
  mask_ = slots - 1;
  slots_ = arena.allocate_array<Slot>(slots, owner);
  max_keys_ = max_keys;
  clear();
}

void CellIndex::clear() noexcept {
  std::fill(slots_.begin(), slots_.end(), Slot{});
  size_ = 0;
}

std::uint32_t CellIndex::find(CellKey key) const noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    const Slot& s = slots_[slot];
    if (s.value == kAbsent) {
      return kAbsent;
    }
    if (s.key == key) {
      return s.value;
    }
  }
}

bool CellIndex::find_or_insert(CellKey key, std::uint32_t value, std::uint32_t& found) noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    Slot& s = slots_[slot];
    if (s.value == kAbsent) {
      if (size_ == max_keys_) {
        return false;
      }
      s = Slot{key, value};
      ++size_;
      found = value;
      return true;
    }
    if (s.key == key) {
      found = s.value;
      return true;
    }
  }
}

// ---- VoxelGrid ----

void VoxelGrid::init(Arena& arena, double voxel_size_m, std::size_t max_voxels) {
  BLOCKMAP_CHECK_MSG(voxel_size_m > 0.0 && max_voxels > 0, "voxel size and capacity must be > 0");
  voxel_size_m_ = voxel_size_m;
  inverse_size_ = static_cast<float>(1.0 / voxel_size_m);
  size_m_ = static_cast<float>(voxel_size_m);
  // At most half full: short probe sequences.
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(2 * max_voxels, 64));
  shift_ = 64u - static_cast<std::uint32_t>(std::countr_zero(slots));
  mask_ = slots - 1;
  slots_ = arena.allocate_array<Voxel>(slots, "planes.voxel_grid");
  occupied_ = arena.allocate_array<std::uint32_t>(max_voxels, "planes.voxel_grid");
  block_index_.init(arena, max_voxels, "planes.voxel_grid");
  block_masks_ = arena.allocate_array<std::uint64_t>(max_voxels, "planes.voxel_grid");
  count_ = 0;
  clear();
}

void VoxelGrid::clear() noexcept {
  // Few voxels in a large table: empty just their slots. Linear probing stays consistent
  // when keys are removed newest first.
  if (count_ * 8 < slots_.size()) {
    for (std::size_t i = count_; i-- > 0;) {
      slots_[occupied_[i]].key = kNoCell;
    }
  } else {
    for (Voxel& slot : slots_) {
      slot.key = kNoCell;
    }
  }
  count_ = 0;
  block_index_.clear();
  block_count_ = 0;
  last_index_ = CellIndex::kAbsent;
  counters_ = Counters{};
}

std::uint32_t VoxelGrid::find(CellKey key) const noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    const CellKey k = slots_[slot].key;
    if (k == key) {
      return static_cast<std::uint32_t>(slot);
    }
    if (k == kNoCell) {
      return CellIndex::kAbsent;
    }
  }
}

std::uint32_t VoxelGrid::find_or_create(CellKey key) noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    Voxel& voxel = slots_[slot];
    if (voxel.key == key) {
      return static_cast<std::uint32_t>(slot);
    }
    if (voxel.key == kNoCell) {
      if (count_ == occupied_.size()) {
        return CellIndex::kAbsent;
      }
      voxel = Voxel{.key = key};
      occupied_[count_++] = static_cast<std::uint32_t>(slot);
      const auto cell = unpack_cell(key);
      mark_in_block(cell.x(), cell.y(), cell.z());
      return static_cast<std::uint32_t>(slot);
    }
  }
}

void VoxelGrid::mark_in_block(std::int64_t x, std::int64_t y, std::int64_t z) noexcept {
  std::uint32_t block = 0;
  // As many blocks as voxels at most: the insert cannot fail when the voxel was created.
  if (block_index_.find_or_insert(pack_cell(x >> 2, y >> 2, z >> 2),
                                  static_cast<std::uint32_t>(block_count_), block) &&
      block == block_count_) {
    block_masks_[block_count_++] = 0;
  }
  block_masks_[block] |= std::uint64_t{1} << (((x & 3) << 4) | ((y & 3) << 2) | (z & 3));
}

std::uint64_t VoxelGrid::block_mask(std::int64_t bx, std::int64_t by,
                                    std::int64_t bz) const noexcept {
  const std::uint32_t block = block_index_.find(pack_cell(bx, by, bz));
  return block == CellIndex::kAbsent ? 0 : block_masks_[block];
}

Eigen::Vector3f VoxelGrid::centre_m(CellKey key) const noexcept {
  const auto cell = unpack_cell(key);
  return ((cell.cast<double>().array() + 0.5) * voxel_size_m_).matrix().cast<float>();
}

Eigen::Vector3f VoxelGrid::centroid_m(const Voxel& voxel) const noexcept {
  const float n = static_cast<float>(std::max<std::uint32_t>(voxel.point_count, 1));
  return centre_m(voxel.key) + Eigen::Vector3f(voxel.sum_m[0], voxel.sum_m[1], voxel.sum_m[2]) / n;
}

PointMoments VoxelGrid::moments(const Voxel& voxel,
                                const Eigen::Vector3d& origin_m) const noexcept {
  PointMoments local;
  local.weight = voxel.point_count;
  local.sum = Eigen::Vector3f(voxel.sum_m[0], voxel.sum_m[1], voxel.sum_m[2]).cast<double>();
  const float* s = voxel.sum_outer_m2;
  Eigen::Matrix3f outer;
  outer << s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5];
  local.sum_outer = outer.cast<double>();
  return local.shifted(centre_m(voxel.key).cast<double>() - origin_m);
}

void VoxelGrid::add_or_remove(const Eigen::Vector3f& point_m, int sign) noexcept {
  if (!point_m.allFinite()) {
    ++counters_.points_dropped_nonfinite;
    return;
  }
  const Eigen::Vector3f scaled = point_m * inverse_size_;
  const Eigen::Vector3f floored = scaled.array().floor();
  const auto x = static_cast<std::int64_t>(floored.x());
  const auto y = static_cast<std::int64_t>(floored.y());
  const auto z = static_cast<std::int64_t>(floored.z());
  if (!cell_in_range(x, y, z)) {
    ++counters_.points_dropped_range;
    return;
  }
  const CellKey key = pack_cell(x, y, z);
  // Consecutive points of a scan often fall in the same voxel: remember the last one.
  if (key != last_key_ || last_index_ == CellIndex::kAbsent) {
    const std::uint32_t id = find_or_create(key);
    if (id == CellIndex::kAbsent) {
      ++counters_.points_dropped_full;
      return;
    }
    last_key_ = key;
    last_index_ = id;
  }
  Voxel& voxel = slots_[last_index_];
  // The offset from the voxel's centre, from the fraction of the scaled point.
  const Eigen::Vector3f local = (scaled - floored).array() - 0.5f;
  const float s = static_cast<float>(sign) * size_m_;
  const float s2 = s * size_m_;
  voxel.point_count =
      static_cast<std::uint32_t>(static_cast<std::int64_t>(voxel.point_count) + sign);
  voxel.sum_m[0] += s * local.x();
  voxel.sum_m[1] += s * local.y();
  voxel.sum_m[2] += s * local.z();
  voxel.sum_outer_m2[0] += s2 * local.x() * local.x();
  voxel.sum_outer_m2[1] += s2 * local.x() * local.y();
  voxel.sum_outer_m2[2] += s2 * local.x() * local.z();
  voxel.sum_outer_m2[3] += s2 * local.y() * local.y();
  voxel.sum_outer_m2[4] += s2 * local.y() * local.z();
  voxel.sum_outer_m2[5] += s2 * local.z() * local.z();
  if (sign > 0) {
    ++counters_.points_added;
  }
}

void VoxelGrid::add_points(std::span<const Eigen::Vector3f> points_m) noexcept {
  constexpr std::size_t kAhead = 8;
  for (std::size_t i = 0; i < points_m.size(); ++i) {
    if (i + kAhead < points_m.size()) {
      const Eigen::Vector3f ahead = points_m[i + kAhead] * inverse_size_;
      if (ahead.allFinite() && ahead.cwiseAbs().maxCoeff() < static_cast<float>(kCellKeyBias - 1)) {
        const Eigen::Vector3f cell = ahead.array().floor();
        __builtin_prefetch(&slots_[home_slot(pack_cell(static_cast<std::int64_t>(cell.x()),
                                                       static_cast<std::int64_t>(cell.y()),
                                                       static_cast<std::int64_t>(cell.z())))]);
      }
    }
    add_or_remove(points_m[i], 1);
  }
}

void VoxelGrid::estimate_shapes(std::span<const std::uint32_t> order, std::uint32_t min_points,
                                double max_planarity_ratio, double max_line_ratio) noexcept {
  const auto planar_ratio_sq = static_cast<float>(max_planarity_ratio * max_planarity_ratio);
  const auto line_ratio_sq = static_cast<float>(max_line_ratio * max_line_ratio);
  const auto size = static_cast<float>(voxel_size_m_);
  // The occupancy of the 3 x 3 x 3 blocks around the current voxel's block, reloaded when the
  // block changes (rarely, when `order` groups voxels by block).
  std::array<std::uint64_t, 27> masks{};
  CellKey mask_block = kNoCell;
  for (const std::uint32_t i : order) {
    Voxel& voxel = slots_[i];
    const auto cell = unpack_cell(voxel.key);
    const std::int64_t bx = cell.x() >> 2;
    const std::int64_t by = cell.y() >> 2;
    const std::int64_t bz = cell.z() >> 2;
    if (pack_cell(bx, by, bz) != mask_block) {
      mask_block = pack_cell(bx, by, bz);
      for (std::int64_t k = 0; k < 27; ++k) {
        masks[static_cast<std::size_t>(k)] =
            block_mask(bx + k / 9 - 1, by + (k / 3) % 3 - 1, bz + k % 3 - 1);
      }
    }
    // The neighbourhood's moments relative to this voxel's centre.
    float n = 0.0f;
    std::array<float, 3> sum{};
    std::array<float, 6> outer{};  // xx xy xz yy yz zz
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const std::int64_t x = cell.x() + dx;
          const std::int64_t y = cell.y() + dy;
          const std::int64_t z = cell.z() + dz;
          const auto which = static_cast<std::size_t>(
              ((x >> 2) - bx + 1) * 9 + ((y >> 2) - by + 1) * 3 + ((z >> 2) - bz + 1));
          if (((masks[which] >> (((x & 3) << 4) | ((y & 3) << 2) | (z & 3))) & 1U) == 0) {
            continue;
          }
          const std::uint32_t other = find(pack_cell(x, y, z));
          if (other == CellIndex::kAbsent || slots_[other].point_count == 0) {
            continue;
          }
          // Parallel axis: moments about the other voxel's centre, moved to this one's.
          const Voxel& v = slots_[other];
          const auto w = static_cast<float>(v.point_count);
          const float tx = static_cast<float>(dx) * size;
          const float ty = static_cast<float>(dy) * size;
          const float tz = static_cast<float>(dz) * size;
          const float sx = v.sum_m[0];
          const float sy = v.sum_m[1];
          const float sz = v.sum_m[2];
          n += w;
          sum[0] += sx + w * tx;
          sum[1] += sy + w * ty;
          sum[2] += sz + w * tz;
          outer[0] += v.sum_outer_m2[0] + 2.0f * sx * tx + w * tx * tx;
          outer[1] += v.sum_outer_m2[1] + sx * ty + tx * sy + w * tx * ty;
          outer[2] += v.sum_outer_m2[2] + sx * tz + tx * sz + w * tx * tz;
          outer[3] += v.sum_outer_m2[3] + 2.0f * sy * ty + w * ty * ty;
          outer[4] += v.sum_outer_m2[4] + sy * tz + ty * sz + w * ty * tz;
          outer[5] += v.sum_outer_m2[5] + 2.0f * sz * tz + w * tz * tz;
        }
      }
    }
    if (n < static_cast<float>(min_points)) {
      voxel.shape = LocalShape::kTooFewPoints;
      continue;
    }
    const Eigen::Vector3f mean = Eigen::Vector3f(sum[0], sum[1], sum[2]) / n;
    Eigen::Matrix3f outer_matrix;
    outer_matrix << outer[0], outer[1], outer[2], outer[1], outer[3], outer[4], outer[2], outer[4],
        outer[5];
    const Eigen::Matrix3f covariance = outer_matrix / n - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> solver;
    solver.computeDirect(covariance);
    const Eigen::Vector3f l = solver.eigenvalues().cwiseMax(0.0f);  // ascending
    if (l(1) <= line_ratio_sq * l(2)) {
      // Thin in two directions: points along one line (a scan line on a far surface).
      voxel.shape = LocalShape::kLinear;
      voxel.axis = solver.eigenvectors().col(2).normalized();
    } else if (l(0) <= planar_ratio_sq * l(1)) {
      // Wide in two directions, thin in the third: a surface.
      voxel.shape = LocalShape::kPlanar;
      voxel.axis = solver.eigenvectors().col(0).normalized();
    } else {
      voxel.shape = LocalShape::kScattered;
    }
  }
}

}  // namespace blockmap::planes
