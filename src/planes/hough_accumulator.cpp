#include "blockmap/planes/hough_accumulator.hpp"

#include <algorithm>
#include <cmath>

#include "blockmap/core/check.hpp"

namespace blockmap::planes {

void HoughAccumulator::init(Arena& arena, const OrientationGrid& grid, double half_range_m,
                            double d_bin_m, std::size_t touched_capacity) {
  BLOCKMAP_CHECK_MSG(half_range_m > 0.0 && d_bin_m > 0.0, "Hough d range and bin must be > 0");
  grid_ = &grid;
  const auto half_bins = static_cast<std::uint32_t>(std::ceil(half_range_m / d_bin_m));
  d_bins_ = 2 * half_bins;
  half_range_m_ = static_cast<float>(half_bins * d_bin_m);
  inverse_bin_m_ = static_cast<float>(1.0 / d_bin_m);
  BLOCKMAP_CHECK_MSG(
      static_cast<std::uint64_t>(grid.row_count()) * d_bins_ < (std::uint64_t{1} << 32),
      "Hough grid too large for 32-bit cell indices");
  votes_ = arena.allocate_array<float>(grid.row_count() * d_bins_, "planes.hough_accumulator");
  touched_ = arena.allocate_array<std::uint32_t>(touched_capacity, "planes.hough_accumulator");
  touched_count_ = 0;
}

void HoughAccumulator::clear() noexcept {
  if (touched_count_ > touched_.size()) {
    std::fill(votes_.begin(), votes_.end(), 0.0f);
  } else {
    for (std::size_t i = 0; i < touched_count_; ++i) {
      votes_[touched_[i]] = 0.0f;
    }
  }
  touched_count_ = 0;
  has_negative_votes_ = false;
}

float HoughAccumulator::window_votes(std::uint32_t row, std::uint32_t d_bin) const noexcept {
  const float* cells = votes_.data() + static_cast<std::size_t>(row) * d_bins_;
  float sum = cells[d_bin];
  if (d_bin > 0) {
    sum += cells[d_bin - 1];
  }
  if (d_bin + 1 < d_bins_) {
    sum += cells[d_bin + 1];
  }
  return sum;
}

bool HoughAccumulator::is_local_maximum(std::uint32_t row, std::uint32_t d_bin,
                                        float window) const noexcept {
  // Beats every neighbour, or ties with it and comes first in grid order: exactly one cell
  // of a plateau is a peak, and always the same one.
  const auto beaten_by = [&](std::uint32_t other_row, std::uint32_t other_bin) {
    const float other = window_votes(other_row, other_bin);
    if (other != window) {
      return other > window;
    }
    return std::make_pair(other_row, other_bin) < std::make_pair(row, d_bin);
  };
  const auto check_row = [&](std::uint32_t other_row, bool flipped) {
    // A flipped neighbour holds the same plane at -d: bin b mirrors to d_bins - 1 - b.
    const std::uint32_t centre = flipped ? d_bins_ - 1 - d_bin : d_bin;
    for (std::int64_t offset = -1; offset <= 1; ++offset) {
      const std::int64_t bin = static_cast<std::int64_t>(centre) + offset;
      if (bin < 0 || bin >= static_cast<std::int64_t>(d_bins_)) {
        continue;
      }
      const auto other_bin = static_cast<std::uint32_t>(bin);
      if ((other_row != row || other_bin != d_bin) && beaten_by(other_row, other_bin)) {
        return false;
      }
    }
    return true;
  };
  if (!check_row(row, false)) {
    return false;
  }
  for (const OrientationGrid::Neighbour& neighbour : grid_->neighbours(row)) {
    if (!check_row(neighbour.row, neighbour.flipped)) {
      return false;
    }
  }
  return true;
}

// One function, longer than most: the walk over the touched cells and the short sorted list
// of the strongest peaks it keeps.
std::size_t HoughAccumulator::find_peaks(float min_votes, std::span<HoughPeak> out) const noexcept {
  std::size_t count = 0;
  const auto consider_bin = [&](std::uint32_t row, std::uint32_t d_bin) {
    const float window = window_votes(row, d_bin);
    if (window < min_votes || !is_local_maximum(row, d_bin, window)) {
      return;
    }
    for (std::size_t i = 0; i < count; ++i) {
      if (out[i].row == row && out[i].d_bin == d_bin) {
        return;  // reached again from another touched cell of its window
      }
    }
    HoughPeak peak{row, d_bin, window, grid_->row_normal(row), bin_centre_m(d_bin)};
    // Keep the strongest out.size(), sorted: insertion into a short list.
    const auto weaker = [&](const HoughPeak& a, const HoughPeak& b) {
      return a.votes != b.votes ? a.votes > b.votes
                                : std::make_pair(a.row, a.d_bin) < std::make_pair(b.row, b.d_bin);
    };
    std::size_t at = count;
    while (at > 0 && weaker(peak, out[at - 1])) {
      --at;
    }
    if (at >= out.size()) {
      return;
    }
    const std::size_t last = std::min(count, out.size() - 1);
    for (std::size_t i = last; i > at; --i) {
      out[i] = out[i - 1];
    }
    out[at] = peak;
    count = std::min(count + 1, out.size());
  };
  // A window's maximum can sit on an empty cell between two voted ones: every touched cell
  // proposes its own window and its two neighbours'.
  const auto consider = [&](std::size_t cell) {
    // Without negative votes, the three windows around a cell hold at most the five cells
    // around it (across a row's end the sum takes in more, never less): most touched cells
    // are done with here, before their row and bin are worked out. (The margin covers the
    // rounding of sums taken in another order.)
    if (!has_negative_votes_) {
      const std::size_t low = cell >= 2 ? cell - 2 : 0;
      const std::size_t high = std::min(cell + 2, votes_.size() - 1);
      float around = 0.0f;
      for (std::size_t c = low; c <= high; ++c) {
        around += votes_[c];
      }
      if (around * 1.001f < min_votes) {
        return;
      }
    }
    const auto row = static_cast<std::uint32_t>(cell / d_bins_);
    const auto d_bin = static_cast<std::uint32_t>(cell % d_bins_);
    if (d_bin > 0) {
      consider_bin(row, d_bin - 1);
    }
    consider_bin(row, d_bin);
    if (d_bin + 1 < d_bins_) {
      consider_bin(row, d_bin + 1);
    }
  };
  if (touched_count_ > touched_.size()) {
    for (std::size_t cell = 0; cell < votes_.size(); ++cell) {
      if (votes_[cell] != 0.0f) {
        consider(cell);
      }
    }
  } else {
    for (std::size_t i = 0; i < touched_count_; ++i) {
      consider(touched_[i]);
    }
  }
  return count;
}

}  // namespace blockmap::planes
