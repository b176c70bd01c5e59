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

// The first slot to probe for `key` in a table of mask + 1 slots (shift = 64 - log2 slots).
// Cells of one 4 x 4 x 4 block hash to 64 consecutive slots: the neighbours of a cell, looked
// up together, share cache lines instead of each costing a miss.
[[nodiscard]] constexpr std::size_t block_local_home_slot(CellKey key, std::uint32_t shift,
                                                          std::size_t mask) noexcept {
  constexpr CellKey kLowBits = (CellKey{3} << 42) | (CellKey{3} << 21) | CellKey{3};
  const CellKey local = (((key >> 42) & 3) << 4) | (((key >> 21) & 3) << 2) | (key & 3);
  const CellKey block = key & ~kLowBits;
  return static_cast<std::size_t>(((block * 0x9E3779B97F4A7C15ull) >> shift) + local) & mask;
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
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return slots_.size_bytes(); }

 private:
  struct Slot {
    CellKey key = 0;
    std::uint32_t value = kAbsent;
  };
  [[nodiscard]] std::size_t home_slot(CellKey key) const noexcept {
    return block_local_home_slot(key, shift_, mask_);
  }
  [[nodiscard]] std::uint64_t block_mask(std::int64_t bx, std::int64_t by,
                                         std::int64_t bz) const noexcept;
  void mark_in_block(std::int64_t x, std::int64_t y, std::int64_t z) noexcept;
  std::span<Slot> slots_;
  std::uint32_t shift_ = 64;
  std::size_t mask_ = 0;
  std::size_t max_keys_ = 0;
  std::size_t size_ = 0;
};

// Marks an empty slot of the voxel table (a packed key never has its top bit set).
inline constexpr CellKey kNoCell = ~CellKey{0};

// In kNoCell slots only the key is meaningful.
struct Voxel {
  CellKey key = kNoCell;
  std::uint32_t point_count = 0;
  float sum_m[3] = {0, 0, 0};                  // sum of (p - centre)
  float sum_outer_m2[6] = {0, 0, 0, 0, 0, 0};  // xx xy xz yy yz zz of (p - centre)
  LocalShape shape = LocalShape::kTooFewPoints;
  Eigen::Vector3f axis = Eigen::Vector3f::UnitZ();  // normal (planar) or direction (linear)
  std::uint32_t axis_cell = 0;  // the orientation cell of the axis (the detector sets it)
  Eigen::Vector3f centroid_m = Eigen::Vector3f::Zero();  // the mean point (the detector sets it)
  std::int32_t owner = -1;  // the plane patch that took this voxel, or -1
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

  // Classifies every voxel by the moments of its 3 x 3 x 3 neighbourhood, visiting them in
  // `order` (indices into voxels(); an order that keeps neighbours together keeps the
  // lookups in cache).
  void estimate_shapes(std::span<const std::uint32_t> order, std::uint32_t min_points,
                       double max_planarity_ratio, double max_line_ratio) noexcept;
  // Adds many points, fetching the slots of points a few ahead while it works on this one.
  void add_points(std::span<const Eigen::Vector3f> points_m) noexcept;

  // The voxels live in the slots of an open-addressing table (a voxel's id is its slot), so a
  // lookup and the voxel it finds are one memory access, and the voxels of one 4 x 4 x 4
  // block lie side by side. occupied() lists the ids in the order the voxels were created.
  [[nodiscard]] std::span<Voxel> slots() noexcept { return slots_; }
  [[nodiscard]] std::span<const Voxel> slots() const noexcept { return slots_; }
  [[nodiscard]] std::span<const std::uint32_t> occupied() const noexcept {
    return occupied_.first(count_);
  }
  [[nodiscard]] std::size_t size() const noexcept { return count_; }
  [[nodiscard]] double voxel_size_m() const noexcept { return voxel_size_m_; }
  [[nodiscard]] Eigen::Vector3f centre_m(CellKey key) const noexcept;
  // The mean of a voxel's points.
  [[nodiscard]] Eigen::Vector3f centroid_m(const Voxel& voxel) const noexcept;
  // A voxel's moments in double, relative to `origin_m`.
  [[nodiscard]] PointMoments moments(const Voxel& voxel,
                                     const Eigen::Vector3d& origin_m) const noexcept;
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return slots_.size_bytes() + occupied_.size_bytes() + block_index_.memory_bytes() +
           block_masks_.size_bytes();
  }

 private:
  void add_or_remove(const Eigen::Vector3f& point_m, int sign) noexcept;
  // The id of `key`'s voxel, or CellIndex::kAbsent.
  [[nodiscard]] std::uint32_t find(CellKey key) const noexcept;
  // The id of `key`'s voxel, created when new; kAbsent when the grid is full.
  [[nodiscard]] std::uint32_t find_or_create(CellKey key) noexcept;
  [[nodiscard]] std::size_t home_slot(CellKey key) const noexcept {
    return block_local_home_slot(key, shift_, mask_);
  }
  [[nodiscard]] std::uint64_t block_mask(std::int64_t bx, std::int64_t by,
                                         std::int64_t bz) const noexcept;
  void mark_in_block(std::int64_t x, std::int64_t y, std::int64_t z) noexcept;

  double voxel_size_m_ = 0.0;
  float inverse_size_ = 0.0f;
  float size_m_ = 0.0f;
  CellKey last_key_ = 0;
  std::uint32_t last_index_ = CellIndex::kAbsent;
  std::span<Voxel> slots_;
  std::span<std::uint32_t> occupied_;
  // Which of the 64 cells of each 4 x 4 x 4 block hold a voxel: most of a voxel's 26
  // neighbours are empty, and a bit test is far cheaper than a failed table lookup.
  CellIndex block_index_;
  std::span<std::uint64_t> block_masks_;
  std::size_t block_count_ = 0;
  std::size_t count_ = 0;
  std::uint32_t shift_ = 64;
  std::size_t mask_ = 0;
  Counters counters_;
};

}  // namespace blockmap::planes
