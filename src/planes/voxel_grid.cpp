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
  const std::size_t slots = std::bit_ceil(2 * max_keys);
  shift_ = 64u - static_cast<std::uint32_t>(std::countr_zero(slots));
  keys_ = arena.allocate_array<CellKey>(slots, owner);
  values_ = arena.allocate_array<std::uint32_t>(slots, owner);
  max_keys_ = max_keys;
  clear();
}

void CellIndex::clear() noexcept {
  std::fill(values_.begin(), values_.end(), kAbsent);
  size_ = 0;
}

std::uint32_t CellIndex::find(CellKey key) const noexcept {
  const std::size_t mask = keys_.size() - 1;
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask) {
    if (values_[slot] == kAbsent) {
      return kAbsent;
    }
    if (keys_[slot] == key) {
      return values_[slot];
    }
  }
}

bool CellIndex::find_or_insert(CellKey key, std::uint32_t value, std::uint32_t& found) noexcept {
  const std::size_t mask = keys_.size() - 1;
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask) {
    if (values_[slot] == kAbsent) {
      if (size_ == max_keys_) {
        return false;
      }
      keys_[slot] = key;
      values_[slot] = value;
      ++size_;
      found = value;
      return true;
    }
    if (keys_[slot] == key) {
      found = values_[slot];
      return true;
    }
  }
}

// ---- VoxelGrid ----

void VoxelGrid::init(Arena& arena, double voxel_size_m, std::size_t max_voxels) {
  BLOCKMAP_CHECK_MSG(voxel_size_m > 0.0, "voxel size must be > 0");
  voxel_size_m_ = voxel_size_m;
  inverse_size_ = static_cast<float>(1.0 / voxel_size_m);
  size_m_ = static_cast<float>(voxel_size_m);
  voxels_ = arena.allocate_array<Voxel>(max_voxels, "planes.voxel_grid");
  index_.init(arena, max_voxels, "planes.voxel_grid");
  clear();
}

void VoxelGrid::clear() noexcept {
  count_ = 0;
  last_index_ = CellIndex::kAbsent;
  index_.clear();
  counters_ = Counters{};
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
  // Consecutive points of a scan mostly fall in the same voxel: remember the last one.
  if (key != last_key_ || last_index_ == CellIndex::kAbsent) {
    std::uint32_t index = 0;
    if (!index_.find_or_insert(key, static_cast<std::uint32_t>(count_), index)) {
      ++counters_.points_dropped_full;
      return;
    }
    if (index == count_) {
      voxels_[count_++] = Voxel{.key = key};
    }
    last_key_ = key;
    last_index_ = index;
  }
  Voxel& voxel = voxels_[last_index_];
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

void VoxelGrid::estimate_shapes(std::uint32_t min_points, double max_planarity_ratio,
                                double max_line_ratio) noexcept {
  const auto planar_ratio_sq = static_cast<float>(max_planarity_ratio * max_planarity_ratio);
  const auto line_ratio_sq = static_cast<float>(max_line_ratio * max_line_ratio);
  const auto size = static_cast<float>(voxel_size_m_);
  for (std::size_t i = 0; i < count_; ++i) {
    Voxel& voxel = voxels_[i];
    const auto cell = unpack_cell(voxel.key);
    // The neighbourhood's moments relative to this voxel's centre.
    float n = 0.0f;
    std::array<float, 3> sum{};
    std::array<float, 6> outer{};  // xx xy xz yy yz zz
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const std::uint32_t other =
              index_.find(pack_cell(cell.x() + dx, cell.y() + dy, cell.z() + dz));
          if (other == CellIndex::kAbsent || voxels_[other].point_count == 0) {
            continue;
          }
          // Parallel axis: moments about the other voxel's centre, moved to this one's.
          const Voxel& v = voxels_[other];
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
