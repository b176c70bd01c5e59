// The samples of the Hough transform: points summed into cubic voxels. A voxel keeps its point
// count and the first and second moments of its points (relative to its centre, so floats
// keep millimetres), not the points: its memory does not grow with the cloud's density.
//
// After all points are in, each voxel gets the shape of its 3 x 3 x 3 neighbourhood: planar
// (with a normal), linear (with a direction: one scan line seen by a sweeping laser), or
// scattered (foliage, clutter), which decides how it votes. A voxel that is scattered at that
// scale gets a second look at the scale of the 3 x 3 x 3 blocks around its block (12 samples
// across): a wall blurred by pose errors of a few tenths of a degree is a thick slab, round
// at 0.6 m and flat at 2.4 m, while a tree crown stays round.
#pragma once

#include <array>
#include <bit>
#include <cstdint>
#include <limits>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/cell_index.hpp"
#include "blockmap/planes/point_moments.hpp"

namespace blockmap::planes {

enum class LocalShape : std::uint8_t { kTooFewPoints, kPlanar, kLinear, kScattered };

// A voxel's sums while points arrive, in a slot of the voxel table (48 bytes: the table
// stays small enough to be cached while points stream in).
struct VoxelSums {
  CellKey key = kNoCell;  // kNoCell: an empty slot; nothing else in it is meaningful
  std::uint32_t point_count = 0;
  float sum_m[3] = {0, 0, 0};                  // sum of (p - centre)
  float sum_outer_m2[6] = {0, 0, 0, 0, 0, 0};  // xx xy xz yy yz zz of (p - centre)

  // Adds a point at `local_m` from the voxel's centre.
  void add_point_m(const Eigen::Vector3f& local_m) noexcept {
    ++point_count;
    sum_m[0] += local_m.x();
    sum_m[1] += local_m.y();
    sum_m[2] += local_m.z();
    sum_outer_m2[0] += local_m.x() * local_m.x();
    sum_outer_m2[1] += local_m.x() * local_m.y();
    sum_outer_m2[2] += local_m.x() * local_m.z();
    sum_outer_m2[3] += local_m.y() * local_m.y();
    sum_outer_m2[4] += local_m.y() * local_m.z();
    sum_outer_m2[5] += local_m.z() * local_m.z();
  }
};

// A sample as the detector sees it: the sums, laid out block by block by compact(), and what
// the shape estimate and the detector add.
struct Voxel : VoxelSums {
  LocalShape shape = LocalShape::kTooFewPoints;
  // Kept shapes: the coarse look made this scattered sample planar (its fine shape is
  // scattered), and the fine estimate's thickness. A block that compact() moves as it was
  // carries its fine shapes in its samples, so the next shape pass need not look them up.
  // (Both sit in what was padding: a Voxel stays 80 bytes.)
  bool coarse_look = false;
  Eigen::Vector3f axis = Eigen::Vector3f::UnitZ();  // normal (planar) or direction (linear)
  std::uint32_t axis_cell = 0;  // the orientation cell of the axis (the detector sets it)
  std::int32_t owner = -1;      // the plane patch that took this voxel, or -1
  std::uint32_t block = 0;      // the index of its block
  float fine_thickness_m = 0.0f;
};

// The moments of some points about a block's centre, as twelve floats (count, the sum, the
// sum of outer products xx xy xz yy yz zz, two unused) so that adding two is three vector
// adds: the shape pass adds up every sample's neighbourhood from them.
struct alignas(16) CentredSums {
  std::array<float, 12> values{};

  void add(const CentredSums& other) noexcept {
    for (std::size_t i = 0; i < values.size(); ++i) {
      values[i] += other.values[i];
    }
  }
  // The same points about a centre `shift_m` behind this one: p' = p + shift_m. Parallel
  // axis: sum (p + t) = s + w t, sum (p + t)(p + t)^T = S + s t^T + t s^T + w t t^T.
  [[nodiscard]] CentredSums moved_by(const std::array<float, 3>& shift_m) const noexcept {
    const float w = values[0];
    const float sx = values[1];
    const float sy = values[2];
    const float sz = values[3];
    const auto [tx, ty, tz] = shift_m;
    // Element by element into a copy: built as one initializer list, GCC assembled the
    // result on the stack and read it back as vectors (a store-forwarding stall each time).
    CentredSums out = *this;
    out.values[1] += w * tx;
    out.values[2] += w * ty;
    out.values[3] += w * tz;
    out.values[4] += 2.0f * sx * tx + w * tx * tx;
    out.values[5] += sx * ty + tx * sy + w * tx * ty;
    out.values[6] += sx * tz + tx * sz + w * tx * tz;
    out.values[7] += 2.0f * sy * ty + w * ty * ty;
    out.values[8] += sy * tz + ty * sz + w * ty * tz;
    out.values[9] += 2.0f * sz * tz + w * tz * tz;
    return out;
  }
};

// How VoxelGrid::estimate_shapes() classifies a sample (PlanesConfig holds the user's values).
struct ShapeOptions {
  std::uint32_t min_points = 5;      // in the 3 x 3 x 3 neighbourhood, for any shape
  double max_planarity_ratio = 0.3;  // sqrt(l0 / l1) of a planar neighbourhood, at most
  double max_line_ratio = 0.15;      // sqrt(l1 / l2) of a linear neighbourhood, at most
  bool coarse_second_look = true;
  // The coarse look also takes a looser slab, up to this sqrt(l0 / l1), when its RMS
  // thickness is at most noisy_slab_per_noise times the cloud's surface noise: a wall blurred
  // by pose errors, not a hedge in a crisp cloud.
  double max_noisy_slab_ratio = 0.5;
  double noisy_slab_per_noise = 4.0;
  bool level_slices = false;  // every point from a level 2D laser (walls_from_lines)
  // Which samples vote in the detection that follows (estimate_shapes' voting points):
  // planar and linear ones, or every sample that holds points.
  bool every_sample_votes = false;
};

// A sample's orientation cell before a section it votes in looks it up (most samples lie in
// sections that are replayed, and never vote). The shape pass sets it.
inline constexpr std::uint32_t kAxisCellUnknown = std::numeric_limits<std::uint32_t>::max();

// How many samples the last shape pass left of each shape.
struct ShapeTally {
  std::uint64_t planar = 0;
  std::uint64_t linear = 0;
  std::uint64_t scattered = 0;
};

class VoxelGrid {
 public:
  struct Counters {
    std::uint64_t points_added = 0;
    std::uint64_t points_dropped_full = 0;   // the voxel was new and the grid full
    std::uint64_t points_dropped_range = 0;  // beyond the packed key range
    std::uint64_t points_dropped_nonfinite = 0;
    std::uint64_t points_erased = 0;  // with their voxels (erase())
  };
  // The samples of one block: voxels()[first, first + count).
  struct BlockRange {
    std::uint32_t first = 0;
    std::uint32_t count = 0;
  };

  // max_blocks: occupied 4 x 4 x 4 blocks (0: as many as voxels, which always suffices); a
  // point whose voxel would need a block beyond it is dropped (points_dropped_full).
  void init(Arena& arena, double voxel_size_m, std::size_t max_voxels, std::size_t max_blocks = 0);
  void clear() noexcept;

  void add_point(const Eigen::Vector3f& point_m) noexcept;
  // Takes a point added before back out (its voxel stays, possibly empty).
  void remove_point(const Eigen::Vector3f& point_m) noexcept;
  // Adds a voxel's sums gathered elsewhere (same voxel size, sums about the voxel's centre).
  void add_sums(const VoxelSums& sums) noexcept;
  // Sets a voxel's sums to what they are now elsewhere (the mapper's window), creating it.
  void set_sums(const VoxelSums& sums) noexcept;
  // Fetches the table slot where `key` lives or would (a hint; nothing changes).
  void prefetch(CellKey key) const noexcept;
  // Takes a voxel out with all its points (a tile left the mapper's window); nothing when it
  // is not there. Its slot, and its block when that empties, serve new voxels; with kept
  // shapes, the blocks around it are estimated again.
  void erase(CellKey key) noexcept;

  // Shapes kept from one estimate_shapes() to the next, until clear(): the next estimates
  // again only the blocks within one block of a block whose samples changed (new, or through
  // add_sums and set_sums), and takes the others' fine shapes as they were. They are the
  // same shapes: a shape reads its 3 x 3 x 3 neighbourhood's sums, and those did not change.
  // (add_point and remove_point do not say which block they change: not with kept shapes.)
  // Call once after init(); takes shape_cache_bytes() from the arena.
  void keep_shapes(Arena& arena);
  [[nodiscard]] static std::size_t shape_cache_bytes(std::size_t max_voxels,
                                                     std::size_t max_blocks = 0) noexcept;
  // Samples whose fine shape the last estimate_shapes() took from the kept ones.
  [[nodiscard]] std::uint64_t shapes_reused() const noexcept { return shapes_reused_; }
  // Adds many points, fetching the slots of points a few ahead while it works on this one.
  void add_points(std::span<const Eigen::Vector3f> points_m) noexcept;

  // Lays the voxels that hold points out densely, block by block (blocks in Z-order of their
  // coordinates, cells in bit order): a block's samples are one range, and a
  // neighbour is found by a bit count instead of a table lookup. Call after adding points
  // and before reading voxels(), blocks or shapes.
  // With kept shapes, a compact() after the first reads from the table only the blocks that
  // changed: the others keep their place in the order and their samples are moved as they
  // are (the same layout as afresh, at the cost of a copy).
  void compact() noexcept;
  // Classifies every sample by the moments of its 3 x 3 x 3 neighbourhood (after compact()).
  // With coarse_second_look, samples that are scattered then get the shape of the 3 x 3 x 3
  // blocks around their block when that is planar. With level_slices (all points from level
  // 2D lasers, walls_from_lines), a neighbourhood flat because it lies in a horizontal slice
  // is classified by its shape within the slice: thin across, a line (a wall's trace).
  // The same pass starts the detection that reads the shapes, so that it need not go over
  // every sample again: each sample's owner and orientation cell are cleared, and, when
  // `voting_points` is given (block_count() entries), each block's entry is set to the points
  // of its samples that vote (ShapeOptions::every_sample_votes).
  void estimate_shapes(const ShapeOptions& options,
                       std::span<std::uint32_t> voting_points = {}) noexcept;
  [[nodiscard]] const ShapeTally& shape_tally() const noexcept { return shape_tally_; }
  // The cloud's surface noise: the mean RMS thickness of the neighbourhoods that the last
  // estimate_shapes() found planar at the fine scale (0 when none were). Sensor noise alone
  // gives millimetres; pose errors between scans give centimetres.
  [[nodiscard]] double surface_noise_m() const noexcept { return surface_noise_m_; }

  // The samples of the last compact(); an id is an index into this span.
  [[nodiscard]] std::span<Voxel> voxels() noexcept { return voxels_.first(count_); }
  [[nodiscard]] std::span<const Voxel> voxels() const noexcept { return voxels_.first(count_); }
  [[nodiscard]] std::size_t size() const noexcept { return count_; }
  // Blocks that were touched, in the order they were first touched (after compact()).
  [[nodiscard]] std::size_t block_count() const noexcept { return block_count_; }
  [[nodiscard]] CellKey block_key(std::size_t block) const noexcept { return block_keys_[block]; }
  [[nodiscard]] BlockRange block_range(std::size_t block) const noexcept {
    return {block_first_[block], static_cast<std::uint32_t>(std::popcount(live_masks_[block]))};
  }
  // The cells of a block that hold samples after compact() (bit_in_block order).
  [[nodiscard]] std::uint64_t live_mask(std::size_t block) const noexcept {
    return live_masks_[block];
  }
  // Whether what the last estimate_shapes() left in a block's samples (keys, sums, shapes,
  // axes) may differ from what the one before it left. Without kept shapes, always.
  [[nodiscard]] bool samples_changed(std::size_t block) const noexcept {
    return !keeping_shapes_ || (block_flags_[block] & kSamplesChanged) != 0;
  }
  // The index of the block with `block_key` (block coordinates), or CellIndex::kAbsent.
  [[nodiscard]] std::uint32_t find_block(CellKey block_key) const noexcept {
    return block_index_.find(block_key);
  }

  [[nodiscard]] double voxel_size_m() const noexcept { return voxel_size_m_; }
  [[nodiscard]] Eigen::Vector3f centre_m(CellKey key) const noexcept;
  // The mean of a voxel's points.
  [[nodiscard]] Eigen::Vector3f centroid_m(const VoxelSums& voxel) const noexcept;
  // A voxel's moments in double, relative to `origin_m`.
  [[nodiscard]] PointMoments moments(const VoxelSums& voxel,
                                     const Eigen::Vector3d& origin_m) const noexcept {
    return moments_of(voxel, voxel_size_m_, origin_m);
  }
  // The same for sums kept elsewhere in this layout (the mapper's window).
  [[nodiscard]] static PointMoments moments_of(const VoxelSums& voxel, double voxel_size_m,
                                               const Eigen::Vector3d& origin_m) noexcept;
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return table_.size_bytes() + voxels_.size_bytes() + block_index_.memory_bytes() +
           block_keys_.size_bytes() + block_masks_.size_bytes() + live_masks_.size_bytes() +
           block_first_.size_bytes() + block_order_.size_bytes() + centred_sums_.size_bytes() +
           block_sums_.size_bytes() + block_summed_.size_bytes() + free_blocks_.size_bytes() +
           serial_of_slot_.size_bytes() + free_serials_.size_bytes() + dense_serial_.size_bytes() +
           kept_.size_bytes() + block_flags_.size_bytes() + changed_cells_.size_bytes() +
           kept_coarse_.size_bytes();
  }
  // Bytes init() takes from the arena for `max_voxels`.
  [[nodiscard]] static std::size_t arena_bytes(std::size_t max_voxels,
                                               std::size_t max_blocks = 0) noexcept;
  // How many voxels of `voxel_size_m` the finite points fall in: a batch tool sizes the grid
  // by it before init. `scratch` must hold one key per point (it is sorted in place).
  [[nodiscard]] static std::size_t count_voxels(std::span<const Eigen::Vector3f> points_m,
                                                double voxel_size_m,
                                                std::span<CellKey> scratch) noexcept;

 private:
  // A point's cell and its offset from the cell's centre in cell units, or why it has none.
  struct LocatedPoint {
    enum class Status : std::uint8_t { kOk, kNonFinite, kOutOfRange };
    Status status = Status::kOk;
    CellKey key = 0;
    Eigen::Vector3f offset = Eigen::Vector3f::Zero();  // in [-0.5, 0.5) per axis
  };
  // Both run once per point: inlined into the loops over points (as calls, passing the
  // located point through memory cost a tenth of the detection).
  [[nodiscard, gnu::always_inline]] static LocatedPoint locate(const Eigen::Vector3f& point_m,
                                                               float inverse_size) noexcept;
  // Adds (sign 1) or takes out (-1) a located point's moments; counts the ones it cannot.
  [[gnu::always_inline]] void accumulate(const LocatedPoint& point, int sign) noexcept;
  // The slot of `key`'s voxel, or the empty slot where it would go.
  [[nodiscard]] std::size_t probe_table(CellKey key) const noexcept {
    return probe(
        home_slot(key), mask_, [this](std::size_t at) { return table_[at].key == kNoCell; },
        [this, key](std::size_t at) { return table_[at].key == key; });
  }
  // The slot of `key`'s voxel, or CellIndex::kAbsent.
  [[nodiscard]] std::uint32_t find(CellKey key) const noexcept {
    const std::size_t slot = probe_table(key);
    return table_[slot].key == kNoCell ? CellIndex::kAbsent : static_cast<std::uint32_t>(slot);
  }
  // The slot of `key`'s voxel, created when new; kAbsent when the grid is full.
  [[nodiscard]] std::uint32_t find_or_create(CellKey key) noexcept;
  [[nodiscard]] std::size_t home_slot(CellKey key) const noexcept {
    return block_local_home_slot(key, shift_, mask_);
  }
  // compact()'s steps: the blocks in Z-order (the blocks placed before keep their order, new
  // ones are sorted and merged in, with kept shapes); every block read from the table; or
  // only the changed ones, the others' samples moved to their new places.
  void order_blocks(bool keep_placed) noexcept;
  void lay_out_all_blocks() noexcept;
  void lay_out_changed_blocks() noexcept;
  // lay_out_changed_blocks()'s steps: every block's new place (the changed ones' live cells
  // read again), the kept blocks' samples moved there, the changed blocks' read from the table.
  void place_blocks_keeping_order() noexcept;
  void move_kept_blocks() noexcept;
  void load_changed_blocks() noexcept;
  // Whether the next compact() reads this block from the table again (new or changed).
  struct BlockOrder;
  [[nodiscard]] bool reloaded(const BlockOrder& entry) const noexcept;
  // Fetches the table slots of block_order_[i]'s cells when it is reloaded (a hint).
  void prefetch_if_reloaded(std::size_t i) const noexcept;
  // Before block_order_[i] is read: the reloaded block kPrefetchAheadBlocks on is fetched
  // (and, at the first, those before it).
  void prefetch_reloaded_ahead_of(std::size_t i) const noexcept;
  // A walk over the blocks fetches the slots of the block this many places on (the table is
  // tens of MiB: a block's cells are a cache miss each).
  static constexpr std::size_t kPrefetchAheadBlocks = 16;
  // Fetches the table slots of a block's cells into the cache (a hint, no effect otherwise).
  void prefetch_block_cells(std::uint32_t block) const noexcept;
  // The table slot of the cell at `bit` of a block (a cell marked in its block).
  [[nodiscard]] std::uint32_t slot_of_cell(std::uint32_t block, std::uint32_t bit) const noexcept;
  // The cells of a block that hold points now (reads the table).
  [[nodiscard]] std::uint64_t live_cells(std::uint32_t block) const noexcept;
  // Reads the samples of a block's `cells` that hold points from the table into the layout
  // at `first`; returns those cells (one pass: the full layout needs no count first).
  std::uint64_t load_block(std::uint32_t block, std::uint64_t cells, std::size_t first) noexcept;
  // Moves `count` laid-out samples (sums, centred sums, serials) from `from` to `to`.
  void move_samples(std::size_t from, std::size_t to, std::size_t count) noexcept;
  // Marks the cell in its block, creating the block; false when that needs one too many.
  bool mark_in_block(std::int64_t x, std::int64_t y, std::int64_t z) noexcept;
  // Unmarks an erased cell; a block left empty is erased too.
  void unmark_in_block(CellKey key) noexcept;
  // The live masks and first sample ids of the 27 blocks around one block (index
  // (dx + 1) * 9 + (dy + 1) * 3 + dz + 1): a neighbour's id is a bit count away.
  struct BlockNeighbourhood {
    std::array<std::uint64_t, 27> live_masks{};
    std::array<std::uint32_t, 27> first{};
    std::array<std::uint64_t, 27> changed{};  // with kept shapes: changed_cells_
  };
  void load_neighbourhood(std::int64_t bx, std::int64_t by, std::int64_t bz, std::uint64_t live,
                          BlockNeighbourhood& out) const noexcept;
  // The squared limits of one estimate_shapes() pass, in float as the shape pass works.
  struct ShapeLimits {
    float planar_ratio_sq = 0.0f;
    float line_ratio_sq = 0.0f;
    float min_points = 0.0f;
    bool level_slices = false;
    float noisy_slab_ratio_sq = 0.0f;      // the coarse look's looser ratio for thin slabs
    float noisy_slab_thickness_m2 = 0.0f;  // ... at most this thick (variance)
  };
  // With kept shapes: the blocks within one block of a changed block are marked stale.
  void mark_stale_blocks() noexcept;
  // The block with this key and the 26 around it (those that exist) are stale.
  void mark_stale_around(CellKey block_key, std::uint8_t flags) noexcept;
  // With kept shapes: the coarse look made the block's scattered samples planar (or not).
  void note_coarse_look(std::uint32_t block, bool applied) noexcept;
  void mark_changed(CellKey key) noexcept;  // a sample's sums
  // The slot for sums.key, created when new; kAbsent, its points counted as dropped, when
  // the key is out of range or the grid full.
  [[nodiscard]] std::uint32_t slot_for(const VoxelSums& sums) noexcept;
  // With kept shapes: the block of this cell changed.
  void sums_changed(CellKey key) noexcept;
  // The fine shape of every sample; adds up the planar samples' thicknesses and count.
  // Also counts the shapes and the voting points, and marks the blocks holding scattered
  // samples (kHoldsScattered), for the coarse look.
  void estimate_fine_shapes(const ShapeLimits& limits, bool every_sample_votes,
                            std::span<std::uint32_t> voting_points, double& thickness_sum_m,
                            std::uint64_t& planar_count) noexcept;
  // Sets the sample's shape; returns its neighbourhood's RMS thickness when planar, else 0.
  float estimate_shape(Voxel& voxel, const BlockNeighbourhood& around,
                       const ShapeLimits& limits) const noexcept;
  [[nodiscard]] CentredSums sum_block(std::uint32_t block) const noexcept;
  // The planar normal of the 3 x 3 x 3 blocks around block (bx, by, bz), or zero when they
  // are not planar. Sums the blocks it needs first.
  [[nodiscard]] Eigen::Vector3f coarse_normal(std::uint32_t block,
                                              const ShapeLimits& limits) noexcept;
  // The second look over the blocks that hold scattered samples.
  // compact(): the block sums that no longer hold are summed again when a coarse look needs them.
  void forget_block_sums() noexcept;
  void take_coarse_look(const ShapeOptions& options, ShapeLimits limits,
                        std::span<std::uint32_t> voting_points) noexcept;
  // The spread of the 3 x 3 x 3 blocks around one block: its two smallest eigenvalues, and
  // the normal when `limits` may take it (always without limits: the spread is kept).
  struct CoarseSpread {
    Eigen::Vector3f normal = Eigen::Vector3f::Zero();
    float point_count = 0.0f;
    float thickness_m2 = 0.0f;  // the smallest eigenvalue
    float width_m2 = 0.0f;      // the middle one
    bool known = false;         // kept: computed since the block's neighbourhood last changed
  };
  [[nodiscard]] CoarseSpread coarse_spread(std::int64_t bx, std::int64_t by, std::int64_t bz,
                                           const ShapeLimits* limits) noexcept;
  // Whether the limits make the spread a surface (ignoring_normal: before the normal is
  // known, the test of the ratios alone).
  [[nodiscard]] static bool coarse_normal_of(const CoarseSpread& spread, const ShapeLimits& limits,
                                             bool ignoring_normal) noexcept;

  double voxel_size_m_ = 0.0;
  double surface_noise_m_ = 0.0;
  float inverse_size_ = 0.0f;
  float size_m_ = 0.0f;
  CellKey last_key_ = 0;
  std::uint32_t last_index_ = CellIndex::kAbsent;
  std::span<VoxelSums> table_;  // open addressing, linear probing, at most half full
  std::size_t slot_count_ = 0;  // voxels in the table
  std::span<Voxel> voxels_;     // dense, block by block (compact())
  std::size_t count_ = 0;
  // Blocks: their keys in first-touch order, which cells were touched, which hold points at
  // the last compact(), and the id of their first sample.
  CellIndex block_index_;
  std::span<CellKey> block_keys_;
  std::span<std::uint64_t> block_masks_;
  std::span<std::uint64_t> live_masks_;
  std::span<std::uint32_t> block_first_;
  struct BlockOrder {
    std::uint64_t code = 0;  // Z-order of the block's coordinates
    std::uint32_t block = 0;
    std::uint32_t first = 0;  // its first sample in the layout of the compact() that placed it
  };
  static constexpr std::uint32_t kNotLaidOut = 0xFFFFFFFFu;
  std::span<BlockOrder> block_order_;    // blocks as compact() laid them out
  std::size_t ordered_blocks_ = 0;       // entries of block_order_ (block_count_ then)
  std::span<CentredSums> centred_sums_;  // per sample, about its block's centre (compact())
  std::span<CentredSums> block_sums_;    // per block, when a coarse look needs it
  // Per block: kSummed, block_sums_ holds its sums (kept from one compact() to the next with
  // kept shapes, for the blocks whose samples did not change); kHoldsScattered, the fine pass
  // left scattered samples in it.
  std::span<std::uint8_t> block_summed_;
  static constexpr std::uint8_t kSummed = 1;
  static constexpr std::uint8_t kHoldsScattered = 2;
  ShapeTally shape_tally_;
  // Indices of erased blocks, for new ones (an erased block stays in the index range with no
  // cells until then).
  std::span<std::uint32_t> free_blocks_;
  std::size_t free_block_count_ = 0;
  // Kept shapes (keep_shapes()): each voxel's serial (given at creation, taken back by
  // erase(); compact() does not change it), by table slot and by dense id; the fine shape of
  // each serial; per block, kChanged, kStale and kAllStale, and which of its cells changed
  // and which need their fine shape estimated again.
  struct KeptShape {
    Eigen::Vector3f axis = Eigen::Vector3f::UnitZ();
    float thickness_m = 0.0f;
    LocalShape shape = LocalShape::kTooFewPoints;
    bool valid = false;
  };
  static constexpr std::uint8_t kChanged = 1;
  // A block within one block of a change: its coarse spread is estimated again.
  static constexpr std::uint8_t kStale = 2;
  // Every fine shape of the block is estimated again (a block next to it was emptied).
  static constexpr std::uint8_t kAllStale = 8;
  // In block_order_ under its present key: the next compact() keeps its place, and moves its
  // samples as they are unless it changed (kept until the block's index serves a new key).
  static constexpr std::uint8_t kPlaced = 4;
  // Its samples were read from the table by this compact() (new, changed or laid out afresh):
  // they carry no shapes, which come from kept_ where they are not estimated again.
  static constexpr std::uint8_t kLoaded = 16;
  // During a shape pass: a fine shape was estimated again, or the coarse look's normal for
  // the block's scattered samples came or went or moved.
  static constexpr std::uint8_t kReshaped = 32;
  // The last coarse look made the block's scattered samples planar.
  static constexpr std::uint8_t kCoarseApplied = 64;
  // After a shape pass: changed, loaded or reshaped in it (samples_changed()).
  static constexpr std::uint8_t kSamplesChanged = 128;
  bool keeping_shapes_ = false;
  std::span<std::uint32_t> serial_of_slot_;
  std::span<std::uint32_t> free_serials_;  // serials of erased voxels, for new ones
  std::size_t free_serial_count_ = 0;
  std::uint32_t next_serial_ = 0;
  std::span<std::uint32_t> dense_serial_;
  std::span<KeptShape> kept_;
  std::span<std::uint8_t> block_flags_;
  // Per block, bit_in_block order: the cells whose sums changed since the last shapes.
  std::span<std::uint64_t> changed_cells_;
  void mark_cell_changed(std::uint32_t block, std::uint32_t bit) noexcept;
  // The cells of a block whose 3 x 3 x 3 neighbourhood holds a changed cell (their fine
  // shapes are estimated again), from its loaded neighbourhood, across block borders.
  [[nodiscard]] static std::uint64_t stale_cells(const BlockNeighbourhood& around) noexcept;
  std::span<CoarseSpread> kept_coarse_;  // per block, with kept shapes
  std::uint64_t shapes_reused_ = 0;
  std::size_t block_count_ = 0;
  std::uint32_t shift_ = 64;
  std::size_t mask_ = 0;
  Counters counters_;
};

}  // namespace blockmap::planes
