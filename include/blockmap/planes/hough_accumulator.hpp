// The fixed-grid Hough accumulator of one section: rows are the searched normal directions of
// an OrientationGrid, columns are bins of the plane offset d (relative to the section's
// centre, d = n . p). The paper's parameterisation, d = x sin(theta) cos(phi) + y sin(theta)
// sin(phi) + z cos(theta), is n . p for the row's unit normal n.
//
// Votes can be added and taken back (a negative weight), so a window that forgets points can
// keep its accumulator. Only touched cells are cleared, so a section costs its votes, not the
// size of the grid.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/orientation_grid.hpp"

namespace blockmap::planes {

struct HoughPeak {
  std::uint32_t row = 0;
  std::uint32_t d_bin = 0;
  float votes = 0.0f;  // the cell's and its two neighbours' in d
  Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();
  float d_m = 0.0f;  // the bin centre, relative to the section centre
};

class HoughAccumulator {
 public:
  // d covers [-half_range_m, half_range_m] in bins of d_bin_m (a whole, even number of them,
  // so that -d and d fall in mirrored bins). touched_capacity bounds the cells remembered
  // for clearing; beyond it, clear() zeroes the whole grid.
  void init(Arena& arena, const OrientationGrid& grid, double half_range_m, double d_bin_m,
            std::size_t touched_capacity);

  void clear() noexcept;

  // One sample of `weight` points at position_m (relative to the section centre) votes for
  // the plane through it in the given row. Offsets outside the range are not counted.
  void vote(std::uint32_t row, const Eigen::Vector3f& position_m, float weight) noexcept {
    vote_rows(std::span<const std::uint32_t>(&row, 1), position_m, weight);
  }

  // The same for each row of a kernel, in order. What every vote reads is read once: the
  // stores into the float grid would otherwise make the compiler read the bin size, the range
  // and the row normals' arrays again at every vote (they could be the same floats).
  void vote_rows(std::span<const std::uint32_t> rows, const Eigen::Vector3f& position_m,
                 float weight) noexcept {
    const Eigen::Vector3f* normals = grid_->cell_normals().data();
    const std::uint32_t* row_cells = grid_->row_cells().data();
    const float half_range_m = half_range_m_;
    const float inverse_bin_m = inverse_bin_m_;
    const std::uint32_t d_bins = d_bins_;
    float* votes = votes_.data();
    for (const std::uint32_t row : rows) {
      const float d = normals[row_cells[row]].dot(position_m);
      const float bin_f = (d + half_range_m) * inverse_bin_m;
      if (!(bin_f >= 0.0f) || bin_f >= static_cast<float>(d_bins)) {
        continue;
      }
      const std::size_t cell =
          static_cast<std::size_t>(row) * d_bins + static_cast<std::uint32_t>(bin_f);
      if (votes[cell] == 0.0f) {
        remember(cell);
      }
      votes[cell] += weight;
    }
    has_negative_votes_ = has_negative_votes_ || (weight < 0.0f && !rows.empty());
  }

  [[nodiscard]] float votes(std::uint32_t row, std::uint32_t d_bin) const noexcept {
    return votes_[static_cast<std::size_t>(row) * d_bins_ + d_bin];
  }
  // A cell's votes with its two neighbours in d: a plane whose points straddle a bin border
  // is not split in two.
  [[nodiscard]] float window_votes(std::uint32_t row, std::uint32_t d_bin) const noexcept;

  // Cells with at least min_votes window votes and none more in their neighbourhood
  // (neighbouring rows and d bins); strongest first, ties in grid order; at most out.size().
  [[nodiscard]] std::size_t find_peaks(float min_votes, std::span<HoughPeak> out) const noexcept;

  [[nodiscard]] std::uint32_t d_bins() const noexcept { return d_bins_; }
  [[nodiscard]] float bin_centre_m(std::uint32_t d_bin) const noexcept {
    return (static_cast<float>(d_bin) + 0.5f) / inverse_bin_m_ - half_range_m_;
  }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return votes_.size_bytes() + touched_.size_bytes();
  }

 private:
  void remember(std::size_t cell) noexcept {
    if (touched_count_ < touched_.size()) {
      touched_[touched_count_] = static_cast<std::uint32_t>(cell);
    }
    ++touched_count_;  // past capacity: clear() falls back to zeroing everything
  }
  [[nodiscard]] bool is_local_maximum(std::uint32_t row, std::uint32_t d_bin,
                                      float window) const noexcept;

  const OrientationGrid* grid_ = nullptr;
  std::uint32_t d_bins_ = 0;
  float half_range_m_ = 0.0f;
  float inverse_bin_m_ = 0.0f;
  std::span<float> votes_;
  std::span<std::uint32_t> touched_;
  std::size_t touched_count_ = 0;
  bool has_negative_votes_ = false;  // since clear(): find_peaks() cannot bound windows then
};

}  // namespace blockmap::planes
