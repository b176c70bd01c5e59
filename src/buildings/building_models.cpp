// BuildingFitter's model fitting: a group's walls as pieces in its frame, the bounding box,
// the rectangle and the L and T shapes proposed from the pieces, and their scores.
#include <algorithm>
#include <cmath>
#include <limits>

#include "blockmap/buildings/building_fitter.hpp"
#include "blockmap/planes/polygon.hpp"
#include "footprint.hpp"

namespace blockmap::buildings {

using footprint::Box;
using footprint::Edge;
using footprint::edge_of;
using footprint::kSampleStepM;
using footprint::on_line;
using footprint::Piece;
using footprint::to_frame;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The box's low (side 0) or high (side 1) bound along `axis` (0: u, 1: v).
double box_side(const Box& box, int axis, int side) {
  const auto k = static_cast<std::size_t>(axis);
  return side == 0 ? box.lo[k] : box.hi[k];
}

// Whether a piece can tell where a notch is: a wall on that line.
bool wall_on_line(const Piece& piece, int axis, double level, double tolerance_m) {
  return piece.trusted_ends && on_line(piece, axis, level, tolerance_m);
}

// Where the pieces on the box's side `side` of axis `across` (the line {across = box side})
// reach toward `toward` along the other axis; NaN when none lies on that line.
double reach_on_line(std::span<const Piece> pieces, const Box& box, int across, int side,
                     int toward, double tolerance_m) {
  const double level = box_side(box, across, side);
  double reach = kNaN;
  for (const Piece& piece : pieces) {
    if (!wall_on_line(piece, 1 - across, level, tolerance_m)) {
      continue;
    }
    const double end = toward == 0 ? piece.lo : piece.hi;
    if (std::isnan(reach) || (toward == 0 ? end < reach : end > reach)) {
      reach = end;
    }
  }
  return reach;
}

bool strictly_inside(const Piece& piece, const Box& box, double tolerance_m) {
  const int across = 1 - piece.axis;
  return piece.level > box_side(box, across, 0) + tolerance_m &&
         piece.level < box_side(box, across, 1) - tolerance_m;
}

// The length-weighted level of the pieces running along `axis` strictly inside the box whose
// end comes within `gap_m` of `end` (a notch's wall reaches the box's side); NaN when none.
double interior_level_reaching(std::span<const Piece> pieces, const Box& box, int axis, double end,
                               double tolerance_m, double gap_m) {
  double weighted = 0.0;
  double weight = 0.0;
  for (const Piece& piece : pieces) {
    if (!piece.trusted_ends || piece.axis != axis || !strictly_inside(piece, box, tolerance_m)) {
      continue;
    }
    if (std::min(std::abs(piece.lo - end), std::abs(piece.hi - end)) > gap_m) {
      continue;
    }
    weighted += (piece.hi - piece.lo) * piece.level;
    weight += piece.hi - piece.lo;
  }
  return weight > 0.0 ? weighted / weight : kNaN;
}

// The length-weighted distance from `centre` of the pieces running along `axis` strictly
// inside the box: a symmetric stem's half width. NaN when none.
double interior_half_width(std::span<const Piece> pieces, const Box& box, int axis, double centre,
                           double tolerance_m) {
  double weighted = 0.0;
  double weight = 0.0;
  for (const Piece& piece : pieces) {
    if (!piece.trusted_ends || piece.axis != axis || !strictly_inside(piece, box, tolerance_m)) {
      continue;
    }
    weighted += (piece.hi - piece.lo) * std::abs(piece.level - centre);
    weight += piece.hi - piece.lo;
  }
  return weight > 0.0 ? weighted / weight : kNaN;
}

// Observed walls the model does not explain (unexplained_m), and how far off the rest lie
// (distance_m, a mean over explained_m of wall).
BuildingFitter::ModelScore observed_fit(std::span<const Piece> pieces,
                                        std::span<const Edge> model_edges, double tolerance_m,
                                        double& explained_m) {
  BuildingFitter::ModelScore result;
  for (const Piece& piece : pieces) {
    const double length_m = (piece.b - piece.a).norm();
    const auto samples = static_cast<std::size_t>(std::ceil(length_m / kSampleStepM));
    const double weight_m = length_m / static_cast<double>(samples);
    for (std::size_t i = 0; i < samples; ++i) {
      const Eigen::Vector2d p = piece.a + (static_cast<double>(i) + 0.5) /
                                              static_cast<double>(samples) * (piece.b - piece.a);
      double nearest_m = std::numeric_limits<double>::infinity();
      for (const Edge& edge : model_edges) {
        if (edge.axis == piece.axis) {
          nearest_m = std::min(nearest_m, planes::point_segment_distance(p, edge.point(edge.from),
                                                                         edge.point(edge.to)));
        }
      }
      if (nearest_m > tolerance_m) {
        result.unexplained_m += weight_m;
      } else {
        result.distance_m += weight_m * nearest_m;
        explained_m += weight_m;
      }
    }
  }
  if (explained_m > 0.0) {
    result.distance_m /= explained_m;
  }
  return result;
}

// Model edges in line with an observed wall but not seen along the rest: in view of where
// that wall was seen from, so a model that needs them there is less likely.
double missed_length_m(std::span<const Piece> pieces, std::span<const Edge> model_edges,
                       double tolerance_m) {
  double missed_m = 0.0;
  for (const Edge& edge : model_edges) {
    bool supported = false;
    for (const Piece& piece : pieces) {
      supported = supported || (wall_on_line(piece, edge.axis, edge.level, tolerance_m) &&
                                piece.hi > edge.lo() && piece.lo < edge.hi());
    }
    if (!supported) {
      continue;
    }
    const double length_m = edge.hi() - edge.lo();
    const auto samples = static_cast<std::size_t>(std::ceil(length_m / kSampleStepM));
    const double weight_m = length_m / static_cast<double>(samples);
    for (std::size_t i = 0; i < samples; ++i) {
      const double along =
          edge.lo() + (static_cast<double>(i) + 0.5) / static_cast<double>(samples) * length_m;
      bool seen = false;
      for (const Piece& piece : pieces) {
        seen = seen || (on_line(piece, edge.axis, edge.level, tolerance_m) &&
                        along >= piece.lo - kSampleStepM && along <= piece.hi + kSampleStepM);
      }
      if (!seen) {
        missed_m += weight_m;
      }
    }
  }
  return missed_m;
}

// The lowest and highest level of the trusted pieces along `along` that span the box (ends
// within the tolerance of both sides, kMinSpanShare of its extent); false when none does.
bool spanning_levels(std::span<const Piece> pieces, const Box& box, int along, double tolerance_m,
                     double& low_m, double& high_m) {
  constexpr double kMinSpanShare = 0.75;
  const auto a = static_cast<std::size_t>(along);
  const double extent_m = box.hi[a] - box.lo[a];
  low_m = std::numeric_limits<double>::infinity();
  high_m = -low_m;
  for (const Piece& piece : pieces) {
    const bool spans = piece.axis == along && piece.trusted_ends &&
                       piece.lo <= box.lo[a] + tolerance_m && piece.hi >= box.hi[a] - tolerance_m &&
                       piece.hi - piece.lo >= kMinSpanShare * extent_m;
    if (spans) {
      low_m = std::min(low_m, piece.level);
      high_m = std::max(high_m, piece.level);
    }
  }
  return high_m >= low_m;
}

// With one spanning wall (an L's or a T's outer wall; the one across from it is broken by a
// notch or is the stem's end), the building is on the side that holds most of the walls
// running `across` it: the other bound opens to infinity. False when neither side holds most.
bool open_side_known(std::span<const Piece> pieces, int across, double tolerance_m, double& low_m,
                     double& high_m) {
  if (high_m - low_m > tolerance_m) {
    return true;  // two walls: the building lies between them
  }
  const double level_m = 0.5 * (low_m + high_m);
  double below_m = 0.0;
  double above_m = 0.0;
  for (const Piece& piece : pieces) {
    if (piece.axis == across) {
      below_m += std::max(0.0, std::min(piece.hi, level_m) - piece.lo);
      above_m += std::max(0.0, piece.hi - std::max(piece.lo, level_m));
    }
  }
  constexpr double kInsideShare = 2.0;  // this many times what lies on the other side
  if (below_m >= kInsideShare * above_m) {
    low_m = -std::numeric_limits<double>::infinity();
  } else if (above_m >= kInsideShare * below_m) {
    high_m = std::numeric_limits<double>::infinity();
  } else {
    return false;
  }
  return true;
}

// The index of the box's corner at (side_u, side_v) (0: lo, 1: hi) among its corners
// counter-clockwise: (lo, lo), (hi, lo), (hi, hi), (lo, hi).
std::size_t corner_index(int side_u, int side_v) {
  return side_v == 0 ? static_cast<std::size_t>(side_u) : static_cast<std::size_t>(3 - side_u);
}

// A T's stem half width: from its side walls (running across the bar inside the box), else
// from its front (the wall on the stem side's line); NaN when neither was seen.
double stem_half_width(std::span<const Piece> pieces, const Box& box, int bar_axis, int stem_side,
                       double tolerance_m) {
  const auto a = static_cast<std::size_t>(bar_axis);
  const double centre = 0.5 * (box.lo[a] + box.hi[a]);
  const double from_sides = interior_half_width(pieces, box, 1 - bar_axis, centre, tolerance_m);
  if (!std::isnan(from_sides)) {
    return from_sides;
  }
  const double reach_lo = reach_on_line(pieces, box, 1 - bar_axis, stem_side, 0, tolerance_m);
  const double reach_hi = reach_on_line(pieces, box, 1 - bar_axis, stem_side, 1, tolerance_m);
  return std::isnan(reach_lo) ? kNaN : std::max(centre - reach_lo, reach_hi - centre);
}

}  // namespace

void BuildingFitter::to_pieces(std::span<const std::uint32_t> members, double axis_rad) noexcept {
  piece_count_ = 0;
  for (const std::uint32_t index : members) {
    const WallSegment& segment = segments_[index];
    Piece piece;
    piece.a = to_frame(segment.p0_m, axis_rad);
    piece.b = to_frame(segment.p1_m, axis_rad);
    const Eigen::Vector2d d = piece.b - piece.a;
    piece.axis = std::abs(d.x()) >= std::abs(d.y()) ? 0 : 1;
    piece.level = 0.5 * (piece.a[1 - piece.axis] + piece.b[1 - piece.axis]);
    piece.lo = std::min(piece.a[piece.axis], piece.b[piece.axis]);
    piece.hi = std::max(piece.a[piece.axis], piece.b[piece.axis]);
    piece.segment = index;
    piece.trusted_ends =
        segment.is_tall || segment.support >= config_.min_low_wall_support_per_m *
                                                  (segment.p1_m - segment.p0_m).norm();
    pieces_[piece_count_++] = piece;
  }
}

void BuildingFitter::merge_parallel_pieces() noexcept {
  // One wall seen on two passes with different pose errors comes back as two parallel planes
  // a metre or two apart: overlapping pieces that close are one wall, at their weighted line.
  bool merged = true;
  while (merged) {
    merged = false;
    for (std::size_t i = 0; i < piece_count_ && !merged; ++i) {
      for (std::size_t j = i + 1; j < piece_count_ && !merged; ++j) {
        Piece& a = pieces_[i];
        const Piece& b = pieces_[j];
        if (a.axis != b.axis || std::abs(a.level - b.level) > config_.parallel_merge_offset_m ||
            std::min(a.hi, b.hi) <= std::max(a.lo, b.lo)) {
          continue;
        }
        const double length_a = a.hi - a.lo;
        const double length_b = b.hi - b.lo;
        a.level = (length_a * a.level + length_b * b.level) / (length_a + length_b);
        a.lo = std::min(a.lo, b.lo);
        a.hi = std::max(a.hi, b.hi);
        const auto along = static_cast<Eigen::Index>(a.axis);
        a.a[along] = a.lo;
        a.a[1 - along] = a.level;
        a.b[along] = a.hi;
        a.b[1 - along] = a.level;
        a.segment = length_b > length_a ? b.segment : a.segment;
        a.trusted_ends = a.trusted_ends || b.trusted_ends;
        pieces_[j] = pieces_[--piece_count_];
        merged = true;
      }
    }
  }
}

void BuildingFitter::trim_past_spanning_walls(const Box& box) noexcept {
  // A wall's plane takes in what stands in line with it a little way past its end (the
  // merger joins coplanar planes across gaps, as a tree breaks a wall): a tree's canopy or a
  // parked car, which would make a rectangle an L or T. A wall that spans the building across
  // (its ends within the fit tolerance of both sides, most of its length) is an outer wall of
  // a rectangle, an L or a T (a notch's or a bar's inner wall spans only part of it): nothing
  // of the building lies beyond the outermost such walls.
  for (int across = 0; across < 2; ++across) {
    const std::span<const Piece> pieces = pieces_.first(piece_count_);
    double low_m = 0.0;
    double high_m = 0.0;
    if (spanning_levels(pieces, box, 1 - across, config_.fit_tolerance_m, low_m, high_m) &&
        open_side_known(pieces, across, config_.fit_tolerance_m, low_m, high_m)) {
      cut_pieces_beyond(across, low_m, high_m);
    }
  }
}

void BuildingFitter::cut_pieces_beyond(int across, double low_m, double high_m) noexcept {
  // A piece along `across` that runs on past one of them, less far than it runs between
  // them, is cut there. (One that lies mostly beyond is another wall: two passes of one
  // wall a little more than parallel_merge_offset_m apart both span the building, and the
  // building's other walls run on past both. One that runs on less than the tolerance may
  // be right where the spanning wall is not: walls drawn at different times disagree by
  // the pose error, and the model explains it either way.)
  // A low piece wholly beyond (a parked car's faces, a hedge) is dropped; a tall one may be
  // another building's wall grouped with this one, and the model weighs it.
  const double tolerance_m = config_.fit_tolerance_m;
  const int along = 1 - across;
  for (std::size_t i = 0; i < piece_count_;) {
    Piece& piece = pieces_[i];
    const bool low = !segments_[piece.segment].is_tall;
    const bool parallel_beyond = piece.axis == along && (piece.level < low_m - tolerance_m ||
                                                         piece.level > high_m + tolerance_m);
    const bool across_beyond = piece.axis == across && (piece.hi <= low_m || piece.lo >= high_m);
    if (low && (parallel_beyond || across_beyond)) {
      pieces_[i] = pieces_[--piece_count_];
      continue;
    }
    ++i;
    if (piece.axis != across) {
      continue;
    }
    const double between_m = std::min(piece.hi, high_m) - std::max(piece.lo, low_m);
    const double beyond_m = std::max(0.0, low_m - piece.lo) + std::max(0.0, piece.hi - high_m);
    if (beyond_m <= tolerance_m || beyond_m >= between_m) {
      continue;
    }
    piece.lo = std::max(piece.lo, low_m);
    piece.hi = std::min(piece.hi, high_m);
    const auto k = static_cast<Eigen::Index>(across);
    piece.a[k] = piece.lo;
    piece.a[1 - k] = piece.level;
    piece.b[k] = piece.hi;
    piece.b[1 - k] = piece.level;
  }
}

BuildingFitter::Box BuildingFitter::bounding_box() const noexcept {
  const std::span<const Piece> pieces = pieces_.first(piece_count_);
  Box box;
  box.lo = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  box.hi = {-box.lo[0], -box.lo[1]};
  for (const Piece& piece : pieces) {
    const auto along = static_cast<std::size_t>(piece.axis);
    const auto across = 1 - along;
    box.lo[along] = std::min(box.lo[along], piece.lo);
    box.hi[along] = std::max(box.hi[along], piece.hi);
    box.lo[across] = std::min(box.lo[across], piece.level);
    box.hi[across] = std::max(box.hi[across], piece.level);
  }
  // A wall's ends are known to a section's size (its polygon is made of section planes), its
  // line to centimetres: a side with a wall on it is where that wall is.
  for (std::size_t k = 0; k < 2; ++k) {
    std::array<double, 2> wall_level{kNaN, kNaN};
    for (const Piece& piece : pieces) {
      if (static_cast<std::size_t>(piece.axis) == k) {
        continue;  // runs along k: its level is across
      }
      if (std::abs(piece.level - box.lo[k]) <= config_.fit_tolerance_m &&
          !(piece.level > wall_level[0])) {
        wall_level[0] = piece.level;
      }
      if (std::abs(piece.level - box.hi[k]) <= config_.fit_tolerance_m &&
          !(piece.level < wall_level[1])) {
        wall_level[1] = piece.level;
      }
    }
    // One wall cannot be both sides (a short wall across it would make the box flat): it is
    // the side it is nearer to.
    if (wall_level[0] == wall_level[1]) {
      const bool nearer_lo = wall_level[0] - box.lo[k] <= box.hi[k] - wall_level[1];
      wall_level[nearer_lo ? 1 : 0] = kNaN;
    }
    box.lo[k] = std::isnan(wall_level[0]) ? box.lo[k] : wall_level[0];
    box.hi[k] = std::isnan(wall_level[1]) ? box.hi[k] : wall_level[1];
  }
  return box;
}

void BuildingFitter::add_model(
    BuildingShape shape, const Box& box,
    const std::array<const Eigen::Vector2d*, 4>& inner_corners) noexcept {
  const std::array<Eigen::Vector2d, 4> rect{
      Eigen::Vector2d(box.lo[0], box.lo[1]), Eigen::Vector2d(box.hi[0], box.lo[1]),
      Eigen::Vector2d(box.hi[0], box.hi[1]), Eigen::Vector2d(box.lo[0], box.hi[1])};
  Model& model = models_[model_count_++];
  model.shape = shape;
  model.size = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    const Eigen::Vector2d& corner = rect[k];
    if (inner_corners[k] == nullptr) {
      model.corners[model.size++] = corner;
      continue;
    }
    // A notch: the corner is replaced by the two points where the notch cuts the incoming and
    // outgoing edges, and the notch's inner corner between them.
    const Eigen::Vector2d& inner = *inner_corners[k];
    const Eigen::Vector2d& previous = rect[(k + 3) % 4];
    const Eigen::Vector2d& next = rect[(k + 1) % 4];
    const auto cut = [&](const Eigen::Vector2d& neighbour) {
      return neighbour.x() != corner.x() ? Eigen::Vector2d(inner.x(), corner.y())
                                         : Eigen::Vector2d(corner.x(), inner.y());
    };
    model.corners[model.size++] = cut(previous);
    model.corners[model.size++] = inner;
    model.corners[model.size++] = cut(next);
  }
}

void BuildingFitter::propose_l(const Box& box, int side_u, int side_v) noexcept {
  const std::span<const Piece> pieces = pieces_.first(piece_count_);
  const double tolerance_m = config_.fit_tolerance_m;
  const std::array<int, 2> sides{side_u, side_v};
  const auto side_value = [&](int axis) {
    return sides[static_cast<std::size_t>(axis)] == 0 ? box.lo[static_cast<std::size_t>(axis)]
                                                      : box.hi[static_cast<std::size_t>(axis)];
  };
  // The notch's inner corner, one coordinate at a time: coordinate `k` of the inner corner is
  // the level of the notch's wall that runs along the other axis (seen inside the box), or
  // where the box side's wall along k stops short of the corner.
  std::array<double, 2> inner{kNaN, kNaN};
  for (int k = 0; k < 2; ++k) {
    const int other = 1 - k;
    double level = interior_level_reaching(pieces, box, other, side_value(other), tolerance_m,
                                           config_.corner_gap_m);
    // The walls on the box's line {other = side}, running along k, stop short of the corner.
    const double reach = reach_on_line(pieces, box, other, sides[static_cast<std::size_t>(other)],
                                       sides[static_cast<std::size_t>(k)], tolerance_m);
    if (!std::isnan(reach) && std::abs(side_value(k) - reach) < config_.min_notch_m) {
      return;  // that wall runs into the corner: no notch there
    }
    if (std::isnan(level)) {
      level = reach;
    }
    inner[static_cast<std::size_t>(k)] = level;
  }
  if (std::isnan(inner[0]) && std::isnan(inner[1])) {
    return;  // nothing suggests a notch at this corner
  }
  for (std::size_t k = 0; k < 2; ++k) {
    if (std::isnan(inner[k])) {
      inner[k] = 0.5 * (box.lo[k] + box.hi[k]);  // unseen: the paper's symmetry
    }
    if (inner[k] - box.lo[k] < config_.min_notch_m || box.hi[k] - inner[k] < config_.min_notch_m) {
      return;
    }
  }
  const Eigen::Vector2d corner(inner[0], inner[1]);
  std::array<const Eigen::Vector2d*, 4> inner_corners{};
  inner_corners[corner_index(side_u, side_v)] = &corner;
  add_model(BuildingShape::kL, box, inner_corners);
}

void BuildingFitter::propose_t(const Box& box, int bar_axis, int stem_side) noexcept {
  const std::span<const Piece> pieces = pieces_.first(piece_count_);
  const double tolerance_m = config_.fit_tolerance_m;
  const auto a = static_cast<std::size_t>(bar_axis);
  const auto b = static_cast<std::size_t>(1 - bar_axis);
  const double centre = 0.5 * (box.lo[a] + box.hi[a]);
  const double stem_end = stem_side == 0 ? box.lo[b] : box.hi[b];
  const double half_length = 0.5 * (box.hi[a] - box.lo[a]);
  double half_stem = stem_half_width(pieces, box, bar_axis, stem_side, tolerance_m);
  // The bar's inner side: the bar's walls facing the stem side (running along a inside the
  // box, reaching an end of the bar), else where the bar's end walls stop.
  double bar_level =
      interior_level_reaching(pieces, box, bar_axis, box.lo[a], tolerance_m, config_.corner_gap_m);
  if (std::isnan(bar_level)) {
    bar_level = interior_level_reaching(pieces, box, bar_axis, box.hi[a], tolerance_m,
                                        config_.corner_gap_m);
  }
  for (int end = 0; end < 2; ++end) {
    const double reach = reach_on_line(pieces, box, bar_axis, end, stem_side, tolerance_m);
    if (!std::isnan(reach) && std::abs(reach - stem_end) < config_.min_notch_m) {
      return;  // a bar end runs to the stem's side: no notch there
    }
    if (std::isnan(bar_level) && !std::isnan(reach)) {
      bar_level = reach;
    }
  }
  if (std::isnan(half_stem) && std::isnan(bar_level)) {
    return;
  }
  if (std::isnan(half_stem)) {
    half_stem = half_length / 3.0;
  }
  if (std::isnan(bar_level)) {
    bar_level = 0.5 * (box.lo[b] + box.hi[b]);
  }
  if (half_length - half_stem < config_.min_notch_m || half_stem < 0.5 * config_.min_notch_m ||
      bar_level - box.lo[b] < config_.min_notch_m || box.hi[b] - bar_level < config_.min_notch_m) {
    return;
  }
  Eigen::Vector2d low_corner;
  Eigen::Vector2d high_corner;
  low_corner[static_cast<Eigen::Index>(a)] = centre - half_stem;
  high_corner[static_cast<Eigen::Index>(a)] = centre + half_stem;
  low_corner[static_cast<Eigen::Index>(b)] = bar_level;
  high_corner[static_cast<Eigen::Index>(b)] = bar_level;
  // The notched rectangle corners: both ends (lo and hi along a) of the stem's side.
  std::array<const Eigen::Vector2d*, 4> inner_corners{};
  if (bar_axis == 0) {
    inner_corners[corner_index(0, stem_side)] = &low_corner;
    inner_corners[corner_index(1, stem_side)] = &high_corner;
  } else {
    inner_corners[corner_index(stem_side, 0)] = &low_corner;
    inner_corners[corner_index(stem_side, 1)] = &high_corner;
  }
  add_model(BuildingShape::kT, box, inner_corners);
}

void BuildingFitter::propose_models(const Box& box) noexcept {
  model_count_ = 0;
  add_model(BuildingShape::kRect, box, {});
  for (int side_u = 0; side_u < 2; ++side_u) {
    for (int side_v = 0; side_v < 2; ++side_v) {
      propose_l(box, side_u, side_v);
    }
  }
  for (int bar_axis = 0; bar_axis < 2; ++bar_axis) {
    for (int stem_side = 0; stem_side < 2; ++stem_side) {
      propose_t(box, bar_axis, stem_side);
    }
  }
}

BuildingFitter::ModelScore BuildingFitter::score(const Model& model) const noexcept {
  const double tolerance_m = config_.fit_tolerance_m;
  const std::span<const Piece> pieces = pieces_.first(piece_count_);
  std::array<Edge, kMaxFootprintVertices> edges{};
  for (std::size_t k = 0; k < model.size; ++k) {
    edges[k] = edge_of(model, k);
  }
  const std::span<const Edge> model_edges(edges.data(), model.size);
  double explained_m = 0.0;
  ModelScore result = observed_fit(pieces, model_edges, tolerance_m, explained_m);
  result.missed_m = missed_length_m(pieces, model_edges, tolerance_m);
  double penalty_m = 0.0;
  if (model.shape == BuildingShape::kL) {
    penalty_m = config_.l_penalty_m;
  } else if (model.shape == BuildingShape::kT) {
    penalty_m = config_.t_penalty_m;
  }
  result.cost = 2.0 * result.unexplained_m + result.missed_m +
                result.distance_m / tolerance_m * (explained_m > 0.0 ? 1.0 : 0.0) + penalty_m;
  return result;
}

}  // namespace blockmap::buildings
