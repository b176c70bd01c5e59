// The last detection's sections, kept for the next one (PlanesConfig::keep_shapes, the
// mapper's window). Between two extractions a twentieth of the window's blocks gain points,
// yet every section was voted, peaked and refined again.
//
// A section's planes, and the samples it takes, depend on nothing but its own samples (sums,
// shapes) and on which of them the sections before it had already taken. Both are summed up
// in a signature: a hash of each of its blocks' samples and of the blocks' taken cells when
// the section's turn comes. A section whose signature is the one it had last time gives the
// same planes and takes the same samples, so those are replayed instead: the detection is
// the same, plane for plane, as a detection from scratch (what MapperSim tests byte for byte).
//
// Which section took a sample is kept per cell of each block, as the block's offset in that
// section (a nibble: sections of 2 x 2 x 2 blocks at most). Block indices are the voxel
// grid's, stable until it is cleared (invalidate() forgets everything then) or the block is
// erased; an index that holds another block, or none, starts with nothing taken.
#pragma once

#include <cstdint>
#include <span>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/plane_merger.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::planes {

class SectionCache {
 public:
  // A section that was searched, and what it gave.
  struct Entry {
    CellKey section = 0;
    std::uint64_t signature = 0;
    std::uint32_t first_plane = 0;  // its planes in planes_of()
    std::uint8_t plane_count = 0;   // at most max_planes_per_section (<= 64)
    std::uint8_t took_samples = 0;  // 1 when it took any sample (its claims are recorded)
    // Its free points when it was last searched, up to kMaxSearchedPoints (barren sections:
    // PlanesConfig::barren_section_growth).
    std::uint16_t searched_points = 0;
  };
  static constexpr std::uint16_t kMaxSearchedPoints = 65535;
  struct Counters {
    std::uint64_t sections_replayed = 0;
    std::uint64_t sections_not_kept = 0;  // beyond max_sections: searched again next time
  };
  // Only sections of at most 2 x 2 x 2 blocks can be kept (supports()).
  static constexpr std::uint32_t kMaxBlocksPerSection = 2;
  [[nodiscard]] static bool supports(std::uint32_t blocks_per_section) noexcept {
    return blocks_per_section <= kMaxBlocksPerSection;
  }

  // A salt for begin() from the exclusions a section's refinement asks: a hash of all they
  // hold, the laser positions included.
  [[nodiscard]] static std::uint64_t salt_of(std::span<const PlaneExclusion> exclusions) noexcept;

  void init(Arena& arena, std::size_t max_blocks, std::size_t max_sections,
            std::size_t max_section_planes);
  [[nodiscard]] static std::size_t arena_bytes(std::size_t max_blocks, std::size_t max_sections,
                                               std::size_t max_section_planes) noexcept;
  // The voxel grid started over: nothing kept is valid.
  void invalidate() noexcept;

  // Starts a detection over `grid` (after its shapes are estimated): last time's entries
  // become the ones to look up, and every block is signed. salt: anything else a section's
  // planes depend on (exclusions); a new salt makes every section new.
  void begin(const VoxelGrid& grid, std::uint64_t salt) noexcept;
  // The section's signature now: its blocks (in blocks_of order) and their taken cells.
  [[nodiscard]] std::uint64_t signature(CellKey section,
                                        std::span<const std::uint32_t> blocks) const noexcept;
  // Last time's entry of `section`, or null. Sections must be asked in key order.
  [[nodiscard]] const Entry* previous(CellKey section) noexcept;
  // The planes that last time's `entry` gave, in their order.
  [[nodiscard]] std::span<const SectionPlane> planes_of(const Entry& entry) const noexcept {
    return kept_planes_.subspan(entry.first_plane, entry.plane_count);
  }
  // The cells of `block` that `section` took last time (a mask of bits in the block).
  [[nodiscard]] std::uint64_t taken_by(CellKey section, std::uint32_t block,
                                       CellKey block_key) const noexcept;
  // `section` takes again, in this detection, the cells of `block` it took last time (a
  // replay: what take() would do for each of them); returns them.
  std::uint64_t retake(CellKey section, std::uint32_t block, CellKey block_key) noexcept;
  // Forgets what `section` took in these blocks (it is searched again).
  void forget_taken(CellKey section, std::span<const std::uint32_t> blocks,
                    const VoxelGrid& grid) noexcept;
  // `section` takes the sample at `cell_bit` of `block`.
  void take(CellKey section, std::uint32_t block, CellKey block_key,
            std::uint32_t cell_bit) noexcept;
  // Records this detection's entry of a section that was searched or replayed.
  void record(const Entry& entry) noexcept;
  // Ends the detection: `planes` are every section plane it gave (the merger's), in order.
  // complete: nothing was dropped for capacity, so the entries can be trusted next time.
  void end(std::span<const SectionPlane> planes, bool complete) noexcept;

  [[nodiscard]] bool valid() const noexcept { return valid_; }
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  [[nodiscard]] static std::uint32_t offset_code(CellKey section, CellKey block_key) noexcept;
  [[nodiscard]] std::uint64_t sign_block(const VoxelGrid& grid, std::uint32_t block) const noexcept;
  void forget_block(std::uint32_t block) noexcept;

  std::span<std::uint64_t> block_signatures_;
  std::span<CellKey> block_keys_;         // per block index: the block it held last time
  std::span<std::uint64_t> taken_cells_;  // per block: cells taken so far in this detection
  std::span<std::uint64_t> taken_codes_;  // per block: 64 nibbles (4 words), the taker's offset
  std::span<Entry> entries_[2];
  std::size_t entry_count_[2] = {0, 0};
  std::size_t current_ = 0;  // entries_[current_] is being written; the other is last time's
  std::size_t cursor_ = 0;   // into last time's entries
  std::span<SectionPlane> kept_planes_;
  std::size_t block_count_ = 0;
  std::uint64_t salt_ = 0;
  bool valid_ = false;  // last time's entries hold for this grid
  // block_signatures_ hold for every block whose samples did not change since (cleared by
  // invalidate(): block indices may start over).
  bool signatures_valid_ = false;
  Counters counters_;
};

}  // namespace blockmap::planes
