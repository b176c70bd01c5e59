// BuildingFitter's walls: each edge of the chosen model as the observed walls along it, and
// virtual walls where nothing was seen (occlusions).
#include <algorithm>
#include <array>
#include <cmath>

#include "blockmap/buildings/building_fitter.hpp"
#include "footprint.hpp"

namespace blockmap::buildings {

using footprint::Edge;
using footprint::edge_of;
using footprint::from_frame;
using footprint::on_line;
using footprint::Piece;

namespace {

// Intervals of one footprint edge kept while its walls are laid out.
constexpr std::size_t kMaxEdgeIntervals = 32;

// Where an edge was seen: the part of a piece on its line, with the plane it came from.
struct Interval {
  double lo = 0.0;
  double hi = 0.0;
  std::uint32_t plane_id = 0;
  double z0 = 0.0;
  double z1 = 0.0;
  double plane_length = 0.0;  // the length of the piece plane_id came from
};

// The observed intervals along `edge`, in order, merged where their gap is below min_gap_m
// (the longer piece names the plane); returns how many.
std::size_t observed_intervals(const Edge& edge, std::span<const Piece> pieces,
                               std::span<const WallSegment> segments, double tolerance_m,
                               double min_gap_m,
                               std::array<Interval, kMaxEdgeIntervals>& intervals) {
  std::size_t count = 0;
  for (const Piece& piece : pieces) {
    if (!on_line(piece, edge.axis, edge.level, tolerance_m) || count == intervals.size()) {
      continue;
    }
    const double lo = std::max(piece.lo, edge.lo());
    const double hi = std::min(piece.hi, edge.hi());
    if (hi <= lo) {
      continue;
    }
    const WallSegment& segment = segments[piece.segment];
    intervals[count++] = {lo, hi, segment.plane_id, segment.z0_m, segment.z1_m, hi - lo};
  }
  std::sort(intervals.begin(), intervals.begin() + static_cast<std::ptrdiff_t>(count),
            [](const Interval& x, const Interval& y) { return x.lo < y.lo; });
  std::size_t merged = 0;
  for (std::size_t i = 0; i < count; ++i) {
    if (merged > 0 && intervals[i].lo - intervals[merged - 1].hi < min_gap_m) {
      Interval& last = intervals[merged - 1];
      last.hi = std::max(last.hi, intervals[i].hi);
      last.z0 = std::min(last.z0, intervals[i].z0);
      last.z1 = std::max(last.z1, intervals[i].z1);
      if (intervals[i].plane_length > last.plane_length) {
        last.plane_id = intervals[i].plane_id;
        last.plane_length = intervals[i].plane_length;
      }
    } else {
      intervals[merged++] = intervals[i];
    }
  }
  return merged;
}

}  // namespace

void BuildingFitter::emit_walls(const Model& model, double axis_rad,
                                Building& building) const noexcept {
  const double tolerance_m = config_.fit_tolerance_m;
  const std::span<const Piece> pieces = pieces_.first(piece_count_);
  const double top_z = building.ground_z_m + building.height_m;
  for (std::size_t k = 0; k < model.size; ++k) {
    const Edge edge = edge_of(model, k);
    std::array<Interval, kMaxEdgeIntervals> intervals{};
    const std::size_t merged = observed_intervals(edge, pieces, segments_, tolerance_m,
                                                  config_.min_virtual_gap_m, intervals);
    // Walk the edge in the footprint's order: observed pieces, virtual walls between them.
    const bool forward = edge.to >= edge.from;
    const auto add_wall = [&](double from, double to, const Interval* observed) {
      if (std::abs(to - from) < 1e-6 || building.wall_count == kMaxBuildingWalls) {
        return;
      }
      BuildingWall& wall = building.walls[building.wall_count++];
      wall.p0_m = from_frame(edge.point(from), axis_rad);
      wall.p1_m = from_frame(edge.point(to), axis_rad);
      wall.is_virtual = observed == nullptr;
      wall.plane_id = observed == nullptr ? 0 : observed->plane_id;
      wall.z0_m = observed == nullptr ? building.ground_z_m : observed->z0;
      wall.z1_m = observed == nullptr ? top_z : observed->z1;
    };
    double cursor = edge.from;
    const std::size_t first_wall = building.wall_count;
    for (std::size_t n = 0; n < merged; ++n) {
      const Interval& interval = intervals[forward ? n : merged - 1 - n];
      double start = forward ? interval.lo : interval.hi;
      const double end = forward ? interval.hi : interval.lo;
      if (std::abs(start - cursor) >= config_.min_virtual_gap_m) {
        add_wall(cursor, start, nullptr);  // an occlusion (or the unseen rest of the edge)
      } else {
        start = cursor;  // a gap too small to draw: the observed wall closes it
      }
      add_wall(start, end, &interval);
      cursor = end;
    }
    if (merged == 0 || std::abs(edge.to - cursor) >= config_.min_virtual_gap_m) {
      add_wall(cursor, edge.to, nullptr);
    } else if (building.wall_count > first_wall) {
      // The last observed piece ends within min_virtual_gap_m of the corner: it reaches it.
      building.walls[building.wall_count - 1].p1_m = from_frame(edge.point(edge.to), axis_rad);
    }
  }
}

}  // namespace blockmap::buildings
