// The samples of the Hough transform: points summed into cubic voxels. A voxel keeps its point
// count and the first and second moments of its points (relative to its centre, so floats
// keep millimetres), not the points: its memory does not grow with the cloud's density.
//
// After all points are in, each voxel gets the shape of its 3 x 3 x 3 neighbourhood: planar
// (with a normal), linear (with a direction: one scan line seen by a sweeping laser), or
// scattered (foliage, clutter), which decides how it votes.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/point_moments.hpp"

namespace blockmap::planes {

enum class LocalShape : std::uint8_t { kTooFewPoints, kPlanar, kLinear, kScattered };

// Integer voxel coordinates packed into 64 bits, 21 bits per axis: +-1,048,575 voxels.
using CellKey = std::uint64_t;
inline constexpr std::int64_t kCellKeyBias = std::int64_t{1} << 20;

[[nodiscard]] constexpr CellKey pack_cell(std::int64_t x, std::int64_t y, std::int64_t z) noexcept {
  return (static_cast<CellKey>(x + kCellKeyBias) << 42) |
         (static_cast<CellKey>(y + kCellKeyBias) << 21) | static_cast<CellKey>(z + kCellKeyBias);
}
[[nodiscard]] inline Eigen::Matrix<std::int64_t, 3, 1> unpack_cell(CellKey key) noexcept {
  constexpr CellKey kMask = (CellKey{1} << 21) - 1;
  return {static_cast<std::int64_t>((key >> 42) & kMask) - kCellKeyBias,
          static_cast<std::int64_t>((key >> 21) & kMask) - kCellKeyBias,
          static_cast<std::int64_t>(key & kMask) - kCellKeyBias};
}
[[nodiscard]] constexpr bool cell_in_range(std::int64_t x, std::int64_t y,
                                           std::int64_t z) noexcept {
  return x > -kCellKeyBias && x < kCellKeyBias && y > -kCellKeyBias && y < kCellKeyBias &&
         z > -kCellKeyBias && z < kCellKeyBias;
}

// A fixed-capacity map from cell keys to 32-bit values (open addressing, linear probing).
class CellIndex {
 public:
  static constexpr std::uint32_t kAbsent = 0xFFFFFFFFu;
  void init(Arena& arena, std::size_t max_keys, const char* owner);
  void clear() noexcept;
  // The value of `key`, or kAbsent.
  [[nodiscard]] std::uint32_t find(CellKey key) const noexcept;
  // The slot of `key`, inserting it with `value` when absent; false when full.
  bool find_or_insert(CellKey key, std::uint32_t value, std::uint32_t& found) noexcept;
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return keys_.size_bytes() + values_.size_bytes();
  }

 private:
  [[nodiscard]] std::size_t home_slot(CellKey key) const noexcept {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  std::span<CellKey> keys_;
  std::span<std::uint32_t> values_;
  std::uint32_t shift_ = 64;
  std::size_t max_keys_ = 0;
  std::size_t size_ = 0;
};

struct Voxel {
  CellKey key = 0;
  std::uint32_t point_count = 0;
  float sum_m[3] = {0, 0, 0};                  // sum of (p - centre)
  float sum_outer_m2[6] = {0, 0, 0, 0, 0, 0};  // xx xy xz yy yz zz of (p - centre)
  LocalShape shape = LocalShape::kTooFewPoints;
  Eigen::Vector3f axis = Eigen::Vector3f::UnitZ();  // normal (planar) or direction (linear)
  std::uint32_t axis_cell = 0;  // the orientation cell of the axis (the detector sets it)
  std::int32_t owner = -1;      // the plane patch that took this voxel, or -1
};

class VoxelGrid {
 public:
  struct Counters {
    std::uint64_t points_added = 0;
    std::uint64_t points_dropped_full = 0;   // the voxel was new and the grid full
    std::uint64_t points_dropped_range = 0;  // beyond the packed key range
    std::uint64_t points_dropped_nonfinite = 0;
  };

  void init(Arena& arena, double voxel_size_m, std::size_t max_voxels);
  void clear() noexcept;

  void add_point(const Eigen::Vector3f& point_m) noexcept { add_or_remove(point_m, 1); }
  // Takes a point added before back out (its voxel stays, possibly empty).
  void remove_point(const Eigen::Vector3f& point_m) noexcept { add_or_remove(point_m, -1); }

  // Classifies every voxel by the moments of its 3 x 3 x 3 neighbourhood.
  void estimate_shapes(std::uint32_t min_points, double max_planarity_ratio,
                       double max_line_ratio) noexcept;

  [[nodiscard]] std::span<Voxel> voxels() noexcept { return voxels_.first(count_); }
  [[nodiscard]] std::span<const Voxel> voxels() const noexcept { return voxels_.first(count_); }
  [[nodiscard]] double voxel_size_m() const noexcept { return voxel_size_m_; }
  [[nodiscard]] Eigen::Vector3f centre_m(CellKey key) const noexcept;
  // The mean of a voxel's points.
  [[nodiscard]] Eigen::Vector3f centroid_m(const Voxel& voxel) const noexcept;
  // A voxel's moments in double, relative to `origin_m`.
  [[nodiscard]] PointMoments moments(const Voxel& voxel,
                                     const Eigen::Vector3d& origin_m) const noexcept;
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return voxels_.size_bytes() + index_.memory_bytes();
  }

 private:
  void add_or_remove(const Eigen::Vector3f& point_m, int sign) noexcept;

  double voxel_size_m_ = 0.0;
  float inverse_size_ = 0.0f;
  float size_m_ = 0.0f;
  CellKey last_key_ = 0;
  std::uint32_t last_index_ = CellIndex::kAbsent;
  std::span<Voxel> voxels_;
  std::size_t count_ = 0;
  CellIndex index_;
  Counters counters_;
};

}  // namespace blockmap::planes
