#include "blockmap/buildings/building_fitter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

#include "blockmap/core/angles.hpp"
#include "blockmap/planes/polygon.hpp"

namespace blockmap::buildings {
namespace {

// Observed walls and model edges are compared at points this far apart.
constexpr double kSampleStepM = 0.25;
// Intervals of one footprint edge kept while its walls are laid out.
constexpr std::size_t kMaxEdgeIntervals = 32;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Vertical: the normal within 10 degrees of horizontal (sin 10 deg).
constexpr double kMaxVerticalNormalZ = 0.17364817766693033;

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// The angle between two undirected lines, 0-90 degrees.
double line_angle_deg(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const double c = std::abs(a.normalized().dot(b.normalized()));
  return std::acos(std::min(1.0, c)) / kRadiansPerDegree;
}

Eigen::Vector2d to_frame(const Eigen::Vector2d& p, double axis_rad) {
  const double c = std::cos(axis_rad);
  const double s = std::sin(axis_rad);
  return {c * p.x() + s * p.y(), -s * p.x() + c * p.y()};
}

Eigen::Vector2d from_frame(const Eigen::Vector2d& q, double axis_rad) {
  const double c = std::cos(axis_rad);
  const double s = std::sin(axis_rad);
  return {c * q.x() - s * q.y(), s * q.x() + c * q.y()};
}

// One edge of a rectilinear model: it runs along `axis` at `level`, from `from` to `to` along
// that axis (in the footprint's counter-clockwise order).
struct Edge {
  int axis = 0;
  double level = 0.0;
  double from = 0.0;
  double to = 0.0;
  [[nodiscard]] double lo() const { return std::min(from, to); }
  [[nodiscard]] double hi() const { return std::max(from, to); }
  [[nodiscard]] Eigen::Vector2d point(double along) const {
    return axis == 0 ? Eigen::Vector2d(along, level) : Eigen::Vector2d(level, along);
  }
};

Edge edge_of(const BuildingFitter::Model& model, std::size_t k) {
  const Eigen::Vector2d& a = model.corners[k];
  const Eigen::Vector2d& b = model.corners[(k + 1) % model.size];
  const int axis = std::abs(b.x() - a.x()) >= std::abs(b.y() - a.y()) ? 0 : 1;
  return {axis, a[1 - axis], a[axis], b[axis]};
}

using Piece = BuildingFitter::Piece;
using Box = BuildingFitter::Box;

// The box's low (side 0) or high (side 1) bound along `axis` (0: u, 1: v).
double box_side(const Box& box, int axis, int side) {
  const auto k = static_cast<std::size_t>(axis);
  return side == 0 ? box.lo[k] : box.hi[k];
}

// Whether a piece lies on the line of an edge (same direction, level within tolerance).
bool on_line(const Piece& piece, int axis, double level, double tolerance_m) {
  return piece.axis == axis && std::abs(piece.level - level) <= tolerance_m;
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

}  // namespace

bool wall_segment_of(const msg::PlanePatch& plane, WallSegment& segment) noexcept {
  if (plane.polygon_size < 2 || std::abs(plane.normal.z()) > kMaxVerticalNormalZ) {
    return false;
  }
  const Eigen::Vector2d normal = plane.normal.head<2>();
  const Eigen::Vector2d across = normal.normalized();
  const Eigen::Vector2d along(-across.y(), across.x());
  const double offset_m = across.dot(plane.centroid_m.head<2>());
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  double z0 = lo;
  double z1 = -lo;
  for (std::size_t i = 0; i < plane.polygon_size; ++i) {
    const Eigen::Vector3d& vertex = plane.polygon_m[i];
    const double s = along.dot(vertex.head<2>());
    lo = std::min(lo, s);
    hi = std::max(hi, s);
    z0 = std::min(z0, vertex.z());
    z1 = std::max(z1, vertex.z());
  }
  segment.p0_m = offset_m * across + lo * along;
  segment.p1_m = offset_m * across + hi * along;
  segment.z0_m = z0;
  segment.z1_m = z1;
  segment.plane_id = plane.id;
  segment.is_tall = plane.kind == msg::PlaneKind::kWall;
  segment.support = plane.support;
  return hi > lo;
}

void BuildingFitter::init(Arena& arena, const BuildingsConfig& config,
                          std::size_t free_space_cells) {
  config_ = config;
  tracer_.init(arena, config, free_space_cells);
  if (free_space_cells > 0) {
    block_members_ = arena.allocate_array<std::uint32_t>(config.max_walls, "buildings.blocks");
    side_walls_ = arena.allocate_array<SideWall>(config.max_walls, "buildings.blocks");
  }
  segments_ = arena.allocate_array<WallSegment>(config.max_walls, "buildings.fitter");
  parent_ = arena.allocate_array<std::uint32_t>(config.max_walls, "buildings.fitter");
  order_ = arena.allocate_array<std::uint32_t>(config.max_walls, "buildings.fitter");
  pieces_ = arena.allocate_array<Piece>(config.max_walls, "buildings.fitter");
  roofs_ = arena.allocate_array<Roof>(config.max_walls, "buildings.fitter");
  buildings_ = arena.allocate_array<Building>(config.max_buildings, "buildings.fitter");
  for (PastSet& set : past_sets_) {
    init_past_set(arena, set);
  }
  past_ = 0;
  const std::size_t remembered = 2 * config.max_buildings;
  past_taken_ = arena.allocate_array<std::uint8_t>(remembered, "buildings.fitter");
  past_votes_ = arena.allocate_array<std::uint32_t>(remembered, "buildings.fitter");
  past_remap_ = arena.allocate_array<std::uint32_t>(remembered, "buildings.fitter");
  next_id_ = 1;
}

void BuildingFitter::init_past_set(Arena& arena, PastSet& set) const {
  const std::size_t remembered = 2 * config_.max_buildings;
  set.ids = arena.allocate_array<std::uint32_t>(remembered, "buildings.fitter");
  set.extents = arena.allocate_array<Extent>(remembered, "buildings.fitter");
  set.absent_fits = arena.allocate_array<std::uint16_t>(remembered, "buildings.fitter");
  set.planes = arena.allocate_array<PastPlane>(remembered * kMaxBuildingWalls, "buildings.fitter");
  set.count = 0;
  set.plane_count = 0;
}

namespace {

std::size_t padded(std::size_t bytes) noexcept {
  return bytes + 64;
}

}  // namespace

std::size_t BuildingFitter::past_set_bytes(const BuildingsConfig& config) noexcept {
  const std::size_t remembered = 2 * config.max_buildings;
  return padded(remembered * sizeof(std::uint32_t)) + padded(remembered * sizeof(Extent)) +
         padded(remembered * sizeof(std::uint16_t)) +
         padded(remembered * kMaxBuildingWalls * sizeof(PastPlane));
}

std::size_t BuildingFitter::arena_bytes(const BuildingsConfig& config,
                                        std::size_t free_space_cells) noexcept {
  const std::size_t remembered = 2 * config.max_buildings;
  const std::size_t blocks = free_space_cells == 0
                                 ? 0
                                 : BlockTracer::arena_bytes(config, free_space_cells) +
                                       padded(config.max_walls * sizeof(std::uint32_t)) +
                                       padded(config.max_walls * sizeof(SideWall));
  return blocks + padded(config.max_walls * sizeof(WallSegment)) +
         2 * padded(config.max_walls * sizeof(std::uint32_t)) +
         padded(config.max_walls * sizeof(Piece)) + padded(config.max_walls * sizeof(Roof)) +
         padded(config.max_buildings * sizeof(Building)) + 2 * past_set_bytes(config) +
         padded(remembered) + 2 * padded(remembered * sizeof(std::uint32_t));
}

std::size_t BuildingFitter::memory_bytes() const noexcept {
  return sizeof(*this) + tracer_.memory_bytes() + block_members_.size_bytes() +
         side_walls_.size_bytes() + segments_.size_bytes() + parent_.size_bytes() +
         order_.size_bytes() + pieces_.size_bytes() + roofs_.size_bytes() +
         buildings_.size_bytes() + past_taken_.size_bytes() + past_votes_.size_bytes() +
         past_remap_.size_bytes() +
         std::accumulate(past_sets_.begin(), past_sets_.end(), std::size_t{0},
                         [](std::size_t sum, const PastSet& set) {
                           return sum + set.ids.size_bytes() + set.extents.size_bytes() +
                                  set.absent_fits.size_bytes() + set.planes.size_bytes();
                         });
}

std::span<const Building> BuildingFitter::fit(std::span<const msg::PlanePatch> planes) noexcept {
  begin();
  for (const msg::PlanePatch& plane : planes) {
    add(plane);
  }
  return finish();
}

void BuildingFitter::begin() noexcept {
  has_free_space_ = false;
  segment_count_ = 0;
  roof_count_ = 0;
  building_count_ = 0;
}

void BuildingFitter::add(const msg::PlanePatch& plane) noexcept {
  if (plane.kind == msg::PlaneKind::kRoof) {
    if (roof_count_ == roofs_.size()) {
      ++counters_.roofs_dropped_full;
      return;
    }
    roofs_[roof_count_++] = {plane.centroid_m.head<2>(), plane.centroid_m.z(), plane.support};
    return;
  }
  // 1. Walls to footprint segments, long enough to be a building's.
  const bool low_wall = config_.use_low_walls && plane.kind == msg::PlaneKind::kOther;
  WallSegment segment;
  if ((plane.kind != msg::PlaneKind::kWall && !low_wall) || !wall_segment_of(plane, segment) ||
      (segment.p1_m - segment.p0_m).norm() < config_.min_wall_length_m) {
    return;
  }
  if (segment_count_ == segments_.size()) {
    ++counters_.walls_dropped_full;
    return;
  }
  segments_[segment_count_++] = segment;
}

std::span<const Building> BuildingFitter::finish() noexcept {
  ++counters_.fits;
  counters_.walls_used += segment_count_;
  // 2. Segments that meet at corners or continue one another are one building.
  group_segments();

  // 3. Each group is fitted to a model; groups are listed by their first wall.
  building_count_ = 0;
  std::size_t first = 0;
  while (first < segment_count_) {
    std::size_t last = first + 1;
    while (last < segment_count_ && find_root(order_[last]) == find_root(order_[first])) {
      ++last;
    }
    if (building_count_ == buildings_.size()) {
      ++counters_.buildings_dropped_full;
    } else {
      Building& building = buildings_[building_count_];
      building = Building{};
      if (fit_group(order_.subspan(first, last - first), building)) {
        ++building_count_;
      }
    }
    first = last;
  }
  // A block the robot drove around is one footprint, whatever its walls made.
  add_traced_blocks();
  // 4. Each building keeps its identity from the last fit.
  assign_ids();
  remember_buildings();
  return buildings_.first(building_count_);
}

BuildingFitter::Extent BuildingFitter::extent_of(const Building& building) noexcept {
  Extent extent{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  const auto grow = [&](const Eigen::Vector2d& p) {
    extent.x0 = std::min(extent.x0, p.x());
    extent.y0 = std::min(extent.y0, p.y());
    extent.x1 = std::max(extent.x1, p.x());
    extent.y1 = std::max(extent.y1, p.y());
  };
  for (std::size_t k = 0; k < building.footprint_size; ++k) {
    grow(building.footprint_m[k]);
  }
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    grow(building.walls[w].p0_m);
    grow(building.walls[w].p1_m);
  }
  return extent;
}

std::size_t BuildingFitter::past_match(const Building& building) noexcept {
  const PastSet& past = past_sets_[past_];
  const std::span<const PastPlane> planes = past.planes.first(past.plane_count);
  std::fill_n(past_votes_.begin(), past.count, 0U);
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    const std::uint32_t plane_id = building.walls[w].plane_id;
    if (building.walls[w].is_virtual || plane_id == 0) {
      continue;
    }
    auto it = std::lower_bound(
        planes.begin(), planes.end(), plane_id,
        [](const PastPlane& known, std::uint32_t id) { return known.plane_id < id; });
    for (; it != planes.end() && it->plane_id == plane_id; ++it) {
      ++past_votes_[it->past];
    }
  }
  std::size_t best = past.count;
  std::uint32_t best_votes = 0;
  for (std::size_t p = 0; p < past.count; ++p) {
    if (past_taken_[p] == 0 && past_votes_[p] > best_votes) {
      best = p;
      best_votes = past_votes_[p];
    }
  }
  if (best < past.count) {
    return best;
  }
  // No wall plane in common (the registry replaced them): the one it overlaps most, by at
  // least half of the smaller extent.
  const Extent e = extent_of(building);
  const auto area = [](const Extent& x) {
    return std::max(0.0, x.x1 - x.x0) * std::max(0.0, x.y1 - x.y0);
  };
  double best_share = 0.5;
  for (std::size_t p = 0; p < past.count; ++p) {
    const Extent& q = past.extents[p];
    const Extent overlap{std::max(e.x0, q.x0), std::max(e.y0, q.y0), std::min(e.x1, q.x1),
                         std::min(e.y1, q.y1)};
    const double smaller = std::min(area(e), area(q));
    const double share = smaller > 0.0 ? area(overlap) / smaller : 0.0;
    if (past_taken_[p] == 0 && share >= best_share) {
      best = p;
      best_share = share;
    }
  }
  return best;
}

void BuildingFitter::assign_ids() noexcept {
  const PastSet& past = past_sets_[past_];
  std::fill_n(past_taken_.begin(), past.count, std::uint8_t{0});
  for (Building& building : buildings_.first(building_count_)) {
    const std::size_t match = past_match(building);
    if (match < past.count) {
      building.id = past.ids[match];
      past_taken_[match] = 1;
    } else {
      building.id = next_id_++;
    }
  }
}

void BuildingFitter::remember_buildings() noexcept {
  constexpr std::uint32_t kForgotten = std::numeric_limits<std::uint32_t>::max();
  const PastSet& old = past_sets_[past_];
  PastSet& next = past_sets_[1 - past_];
  next.count = 0;
  next.plane_count = 0;
  // This fit's buildings first,
  for (const Building& building : buildings_.first(building_count_)) {
    const auto index = static_cast<std::uint32_t>(next.count++);
    next.ids[index] = building.id;
    next.extents[index] = extent_of(building);
    next.absent_fits[index] = 0;
    for (std::size_t w = 0; w < building.wall_count; ++w) {
      if (!building.walls[w].is_virtual && building.walls[w].plane_id != 0) {
        next.planes[next.plane_count++] = {building.walls[w].plane_id, index};
      }
    }
  }
  // then those absent from it, for kRememberAbsentFits fits, while there is room.
  for (std::size_t p = 0; p < old.count; ++p) {
    past_remap_[p] = kForgotten;
    if (past_taken_[p] == 0 && old.absent_fits[p] < kRememberAbsentFits &&
        next.count < next.ids.size()) {
      const auto index = static_cast<std::uint32_t>(next.count++);
      next.ids[index] = old.ids[p];
      next.extents[index] = old.extents[p];
      next.absent_fits[index] = static_cast<std::uint16_t>(old.absent_fits[p] + 1);
      past_remap_[p] = index;
    }
  }
  for (const PastPlane& plane : old.planes.first(old.plane_count)) {
    if (past_remap_[plane.past] != kForgotten && next.plane_count < next.planes.size()) {
      next.planes[next.plane_count++] = {plane.plane_id, past_remap_[plane.past]};
    }
  }
  std::sort(next.planes.begin(),
            next.planes.begin() + static_cast<std::ptrdiff_t>(next.plane_count),
            [](const PastPlane& a, const PastPlane& b) {
              return a.plane_id < b.plane_id || (a.plane_id == b.plane_id && a.past < b.past);
            });
  past_ = 1 - past_;
}

std::uint32_t BuildingFitter::find_root(std::uint32_t i) noexcept {
  while (parent_[i] != i) {
    parent_[i] = parent_[parent_[i]];
    i = parent_[i];
  }
  return i;
}

bool BuildingFitter::same_building(const WallSegment& a, const WallSegment& b) const noexcept {
  const Eigen::Vector2d da = a.p1_m - a.p0_m;
  const Eigen::Vector2d db = b.p1_m - b.p0_m;
  const double angle_deg = line_angle_deg(da, db);
  if (angle_deg <= config_.collinear_angle_tolerance_deg) {
    // Pieces of one wall: close across, a gap along no longer than an occlusion.
    const Eigen::Vector2d along = da.normalized();
    const Eigen::Vector2d across(-along.y(), along.x());
    const double offset_m =
        std::max(std::abs(across.dot(b.p0_m - a.p0_m)), std::abs(across.dot(b.p1_m - a.p0_m)));
    const double a_hi = along.dot(da);
    const double b0 = along.dot(b.p0_m - a.p0_m);
    const double b1 = along.dot(b.p1_m - a.p0_m);
    const double gap_m = std::max({0.0, std::min(b0, b1) - a_hi, -std::max(b0, b1)});
    return offset_m <= config_.collinear_offset_m && gap_m <= config_.max_occlusion_gap_m;
  }
  if (std::abs(angle_deg - 90.0) > config_.corner_angle_tolerance_deg) {
    return false;
  }
  // A corner: where the two lines meet lies within corner_gap_m of both walls.
  const double denominator = cross(da, db);
  const double t = cross(b.p0_m - a.p0_m, db) / denominator;
  const Eigen::Vector2d corner = a.p0_m + t * da;
  return planes::point_segment_distance(corner, a.p0_m, a.p1_m) <= config_.corner_gap_m &&
         planes::point_segment_distance(corner, b.p0_m, b.p1_m) <= config_.corner_gap_m;
}

void BuildingFitter::group_segments() noexcept {
  for (std::size_t i = 0; i < segment_count_; ++i) {
    parent_[i] = static_cast<std::uint32_t>(i);
  }
  // No link reaches farther than this: a cheap box test first spares most pairs of a city
  // block the trigonometry of same_building().
  const double reach_m =
      std::max(config_.corner_gap_m, config_.max_occlusion_gap_m) + config_.collinear_offset_m;
  for (std::size_t i = 0; i < segment_count_; ++i) {
    const Eigen::Vector2d low_i = segments_[i].p0_m.cwiseMin(segments_[i].p1_m);
    const Eigen::Vector2d high_i = segments_[i].p0_m.cwiseMax(segments_[i].p1_m);
    for (std::size_t j = i + 1; j < segment_count_; ++j) {
      const Eigen::Vector2d low_j = segments_[j].p0_m.cwiseMin(segments_[j].p1_m);
      const Eigen::Vector2d high_j = segments_[j].p0_m.cwiseMax(segments_[j].p1_m);
      if ((low_j.array() > high_i.array() + reach_m).any() ||
          (low_i.array() > high_j.array() + reach_m).any()) {
        continue;
      }
      if (same_building(segments_[i], segments_[j])) {
        const std::uint32_t ri = find_root(static_cast<std::uint32_t>(i));
        const std::uint32_t rj = find_root(static_cast<std::uint32_t>(j));
        // The smaller index is the root, so a group is named by its first wall.
        parent_[std::max(ri, rj)] = std::min(ri, rj);
      }
    }
  }
  // Group order: by root (each group's first wall), members in their own order.
  for (std::size_t i = 0; i < segment_count_; ++i) {
    order_[i] = static_cast<std::uint32_t>(i);
  }
  std::sort(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(segment_count_),
            [this](std::uint32_t a, std::uint32_t b) {
              const std::uint32_t ra = find_root(a);
              const std::uint32_t rb = find_root(b);
              return ra != rb ? ra < rb : a < b;
            });
}

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
  // parked car. With the filter's poses such a wall ran 3-5 m past its building's corner and
  // made a rectangle an L or T. A wall that spans the building across (its ends within the
  // fit tolerance of both sides, most of its length) is an outer wall of a rectangle, an L
  // or a T (a notch's or a bar's inner wall spans only part of it): nothing of the building
  // lies beyond the outermost such walls.
  constexpr double kMinSpanShare = 0.75;
  const double tolerance_m = config_.fit_tolerance_m;
  for (int across = 0; across < 2; ++across) {
    const int along = 1 - across;  // the direction the spanning walls run
    const auto a = static_cast<std::size_t>(along);
    const double extent_m = box.hi[a] - box.lo[a];
    double low_m = std::numeric_limits<double>::infinity();
    double high_m = -low_m;
    for (std::size_t i = 0; i < piece_count_; ++i) {
      const Piece& piece = pieces_[i];
      const bool spans =
          piece.axis == along && piece.trusted_ends && piece.lo <= box.lo[a] + tolerance_m &&
          piece.hi >= box.hi[a] - tolerance_m && piece.hi - piece.lo >= kMinSpanShare * extent_m;
      if (spans) {
        low_m = std::min(low_m, piece.level);
        high_m = std::max(high_m, piece.level);
      }
    }
    if (!(high_m >= low_m)) {
      continue;  // no wall spans the building: nothing is known to be beyond
    }
    if (high_m - low_m <= tolerance_m) {
      // One such wall (an L's or a T's outer wall; the one across from it is broken by a
      // notch or is the stem's end): the building is on the side that holds most of the
      // walls running across it.
      const double level_m = 0.5 * (low_m + high_m);
      double below_m = 0.0;
      double above_m = 0.0;
      for (std::size_t i = 0; i < piece_count_; ++i) {
        const Piece& piece = pieces_[i];
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
        continue;
      }
    }
    // A piece along `across` that runs on past one of them, less far than it runs between
    // them, is cut there. (One that lies mostly beyond is another wall: two passes of one
    // wall a little more than parallel_merge_offset_m apart both span the building, and the
    // building's other walls run on past both. One that runs on less than the tolerance may
    // be right where the spanning wall is not: walls drawn at different times disagree by
    // the pose error, and the model explains it either way.)
    // A low piece wholly beyond (a parked car's faces, a hedge) is dropped; a tall one may be
    // another building's wall grouped with this one, and the model weighs it.
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
  // Rectangle corners counter-clockwise: (lo, lo), (hi, lo), (hi, hi), (lo, hi).
  const std::size_t index =
      side_v == 0 ? static_cast<std::size_t>(side_u) : static_cast<std::size_t>(3 - side_u);
  inner_corners[index] = &corner;
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
  // The stem's half width: its side walls (running along b inside the box), else the stem's
  // front (the wall on the stem side's line).
  double half_stem = interior_half_width(pieces, box, 1 - bar_axis, centre, tolerance_m);
  if (std::isnan(half_stem)) {
    const double reach_lo = reach_on_line(pieces, box, 1 - bar_axis, stem_side, 0, tolerance_m);
    const double reach_hi = reach_on_line(pieces, box, 1 - bar_axis, stem_side, 1, tolerance_m);
    if (!std::isnan(reach_lo)) {
      half_stem = std::max(centre - reach_lo, reach_hi - centre);
    }
  }
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
  const auto corner_index = [](int side_u, int side_v) {
    return side_v == 0 ? static_cast<std::size_t>(side_u) : static_cast<std::size_t>(3 - side_u);
  };
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
  ModelScore result;
  double explained_m = 0.0;
  std::array<Edge, kMaxFootprintVertices> edges{};
  for (std::size_t k = 0; k < model.size; ++k) {
    edges[k] = edge_of(model, k);
  }
  const std::span<const Edge> model_edges(edges.data(), model.size);
  // Observed walls the model does not explain, and how far off the rest lie.
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
  // Model edges in line with an observed wall but not seen along the rest: in view of where
  // that wall was seen from, so a model that needs them there is less likely.
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
        result.missed_m += weight_m;
      }
    }
  }
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

void BuildingFitter::emit_walls(const Model& model, double axis_rad,
                                Building& building) const noexcept {
  const double tolerance_m = config_.fit_tolerance_m;
  const std::span<const Piece> pieces = pieces_.first(piece_count_);
  struct Interval {
    double lo = 0.0;
    double hi = 0.0;
    std::uint32_t plane_id = 0;
    double z0 = 0.0;
    double z1 = 0.0;
    double plane_length = 0.0;  // the length of the piece plane_id came from
  };
  const double top_z = building.ground_z_m + building.height_m;
  for (std::size_t k = 0; k < model.size; ++k) {
    const Edge edge = edge_of(model, k);
    // The observed intervals along this edge, merged where their gap is small.
    std::array<Interval, kMaxEdgeIntervals> intervals{};
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
      const WallSegment& segment = segments_[piece.segment];
      intervals[count++] = {lo, hi, segment.plane_id, segment.z0_m, segment.z1_m, hi - lo};
    }
    std::sort(intervals.begin(), intervals.begin() + static_cast<std::ptrdiff_t>(count),
              [](const Interval& x, const Interval& y) { return x.lo < y.lo; });
    std::size_t merged = 0;
    for (std::size_t i = 0; i < count; ++i) {
      if (merged > 0 && intervals[i].lo - intervals[merged - 1].hi < config_.min_virtual_gap_m) {
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

void BuildingFitter::set_height(Building& building) const noexcept {
  double ground_z = std::numeric_limits<double>::infinity();
  double wall_top_z = -ground_z;
  for (const Piece& piece : pieces_.first(piece_count_)) {
    ground_z = std::min(ground_z, segments_[piece.segment].z0_m);
    wall_top_z = std::max(wall_top_z, segments_[piece.segment].z1_m);
  }
  // Roof planes over the footprint: their support-weighted height.
  double roof_weighted = 0.0;
  double roof_support = 0.0;
  const std::span<const Eigen::Vector2d> footprint(building.footprint_m.data(),
                                                   building.footprint_size);
  for (const Roof& roof : roofs_.first(roof_count_)) {
    if (footprint.size() >= 3 && planes::inside_polygon(roof.centroid_m, footprint)) {
      roof_weighted += roof.support * roof.z_m;
      roof_support += roof.support;
    }
  }
  building.ground_z_m = ground_z;
  building.height_from_roof = roof_support > 0.0;
  const double top_z = building.height_from_roof ? roof_weighted / roof_support : wall_top_z;
  building.height_m = std::max(0.0, top_z - ground_z);
}

bool BuildingFitter::fit_group(std::span<const std::uint32_t> members,
                               Building& building) noexcept {
  const double axis_rad = dominant_axis(members);
  to_pieces(members, axis_rad);
  merge_parallel_pieces();
  if (piece_count_ > 0) {
    trim_past_spanning_walls(bounding_box());
  }

  // A building needs a wall (low planes only join one) and a corner: walls along both axes.
  bool has_tall_wall = false;
  for (const std::uint32_t index : members) {
    has_tall_wall = has_tall_wall || segments_[index].is_tall;
  }
  if (!has_tall_wall) {
    return false;
  }
  std::array<double, 2> length_along{};
  double observed_m = 0.0;
  for (const Piece& piece : pieces_.first(piece_count_)) {
    length_along[static_cast<std::size_t>(piece.axis)] += piece.hi - piece.lo;
    observed_m += piece.hi - piece.lo;
  }
  if (length_along[0] < config_.min_wall_length_m || length_along[1] < config_.min_wall_length_m) {
    return false;
  }

  // Candidate models, scored; the first of the lowest cost wins (rect before L before T). A
  // box thinner than a wall is a fence's corner or a kerb, not a building.
  const Box box = bounding_box();
  if (box.hi[0] - box.lo[0] < config_.min_wall_length_m ||
      box.hi[1] - box.lo[1] < config_.min_wall_length_m) {
    return false;
  }
  propose_models(box);
  std::size_t best = 0;
  ModelScore best_score = score(models_[0]);
  for (std::size_t m = 1; m < model_count_; ++m) {
    const ModelScore candidate = score(models_[m]);
    if (candidate.cost < best_score.cost) {
      best = m;
      best_score = candidate;
    }
  }
  const Model& model = models_[best];
  const bool explained =
      observed_m - best_score.unexplained_m >= config_.min_explained_share * observed_m;

  building.shape = explained ? model.shape : BuildingShape::kUnknown;
  if (explained) {
    for (std::size_t k = 0; k < model.size; ++k) {
      building.footprint_m[k] = from_frame(model.corners[k], axis_rad);
    }
    building.footprint_size = model.size;
  }
  set_height(building);
  if (!explained) {
    // No model: the observed walls as they are.
    for (const Piece& piece : pieces_.first(piece_count_)) {
      if (building.wall_count == kMaxBuildingWalls) {
        break;
      }
      const WallSegment& segment = segments_[piece.segment];
      building.walls[building.wall_count++] = {segment.p0_m, segment.p1_m, segment.z0_m,
                                               segment.z1_m, false,        segment.plane_id};
    }
    building.confidence = 0.0;
    return true;
  }
  emit_walls(model, axis_rad, building);
  set_confidence(building);
  return true;
}

double BuildingFitter::dominant_axis(std::span<const std::uint32_t> members) const noexcept {
  // Angles times four, so that walls and the walls across them agree.
  double sum_cos = 0.0;
  double sum_sin = 0.0;
  for (const std::uint32_t index : members) {
    const Eigen::Vector2d d = segments_[index].p1_m - segments_[index].p0_m;
    const double angle = std::atan2(d.y(), d.x());
    sum_cos += d.norm() * std::cos(4.0 * angle);
    sum_sin += d.norm() * std::sin(4.0 * angle);
  }
  return 0.25 * std::atan2(sum_sin, sum_cos);
}

void BuildingFitter::set_confidence(Building& building) noexcept {
  double perimeter_m = 0.0;
  double seen_m = 0.0;
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    const double length_m = (building.walls[w].p1_m - building.walls[w].p0_m).norm();
    perimeter_m += length_m;
    seen_m += building.walls[w].is_virtual ? 0.0 : length_m;
  }
  building.confidence = perimeter_m > 0.0 ? seen_m / perimeter_m : 0.0;
}

namespace {

// A building this much inside a traced block is a part of it.
constexpr double kPartOfBlockShare = 0.25;
// A building whose footprint is this much free space is none.
constexpr double kSeenThroughShare = 0.5;

// The share of `building`'s footprint, sampled every metre, where `test` holds; 0 without a
// footprint.
template <class Test>
double footprint_share(const Building& building, Test&& test) {
  constexpr double kStepM = 1.0;
  const std::span<const Eigen::Vector2d> footprint(building.footprint_m.data(),
                                                   building.footprint_size);
  if (footprint.size() < 3) {
    return 0.0;
  }
  Eigen::Vector2d low = footprint[0];
  Eigen::Vector2d high = footprint[0];
  for (const Eigen::Vector2d& p : footprint) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  std::size_t samples = 0;
  std::size_t held = 0;
  for (double y = low.y() + 0.5 * kStepM; y < high.y(); y += kStepM) {
    for (double x = low.x() + 0.5 * kStepM; x < high.x(); x += kStepM) {
      const Eigen::Vector2d p(x, y);
      if (planes::inside_polygon(p, footprint)) {
        ++samples;
        held += test(p) ? 1U : 0U;
      }
    }
  }
  return samples > 0 ? static_cast<double>(held) / static_cast<double>(samples) : 0.0;
}

// The share of `building` inside `block`'s footprint: of its footprint, or of its observed
// walls' middles when it has none.
double share_inside(const Building& building, const Building& block) {
  const std::span<const Eigen::Vector2d> outline(block.footprint_m.data(), block.footprint_size);
  const auto inside = [&](const Eigen::Vector2d& p) { return planes::inside_polygon(p, outline); };
  if (building.footprint_size >= 3) {
    return footprint_share(building, inside);
  }
  std::size_t held = 0;
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    held += inside(0.5 * (building.walls[w].p0_m + building.walls[w].p1_m)) ? 1U : 0U;
  }
  return building.wall_count > 0
             ? static_cast<double>(held) / static_cast<double>(building.wall_count)
             : 0.0;
}

}  // namespace

void BuildingFitter::keep_observed_walls_only(Building& building) noexcept {
  building.shape = BuildingShape::kUnknown;
  building.footprint_size = 0;
  building.confidence = 0.0;
  std::size_t kept = 0;
  for (std::size_t w = 0; w < building.wall_count; ++w) {
    if (!building.walls[w].is_virtual) {
      building.walls[kept++] = building.walls[w];
    }
  }
  building.wall_count = static_cast<std::uint8_t>(kept);
}

double BuildingFitter::free_share(const Building& building) const noexcept {
  return footprint_share(building, [this](const Eigen::Vector2d& p) { return tracer_.is_free(p); });
}

void BuildingFitter::add_traced_blocks() noexcept {
  if (!has_free_space_ || block_members_.empty()) {
    return;
  }
  const std::span<const BlockTracer::Block> blocks = tracer_.find_blocks(free_space_);
  // A footprint that beams went through is no building's: the model closed a box around a
  // car, a hedge or a row of trees, or put it on the side of a facade that the robot saw
  // into. Its seen walls stay, without a model ("unknown").
  for (Building& building : buildings_.first(building_count_)) {
    if (free_share(building) >= kSeenThroughShare) {
      ++counters_.buildings_seen_through;
      keep_observed_walls_only(building);
    }
  }
  for (const BlockTracer::Block& block : blocks) {
    // The block's walls: those whose middle lies within reach of it.
    std::size_t member_count = 0;
    double tall_m = 0.0;
    for (std::uint32_t s = 0; s < segment_count_; ++s) {
      const WallSegment& segment = segments_[s];
      if (tracer_.reaches(block, 0.5 * (segment.p0_m + segment.p1_m), config_.block_wall_reach_m)) {
        block_members_[member_count++] = s;
        tall_m += segment.is_tall ? (segment.p1_m - segment.p0_m).norm() : 0.0;
      }
    }
    if (tall_m < config_.min_block_wall_m) {
      continue;  // ground nobody saw into, with no building along it
    }
    Building traced;
    if (!fit_block(block, block_members_.first(member_count), traced)) {
      continue;
    }
    // The buildings fitted inside the block, or a quarter in it, were parts of it (or
    // clutter before it that a model stretched into it).
    std::size_t kept = 0;
    for (std::size_t b = 0; b < building_count_; ++b) {
      const Extent e = extent_of(buildings_[b]);
      const Eigen::Vector2d centre(0.5 * (e.x0 + e.x1), 0.5 * (e.y0 + e.y1));
      if (!tracer_.reaches(block, centre, config_.block_wall_reach_m) &&
          share_inside(buildings_[b], traced) < kPartOfBlockShare) {
        buildings_[kept++] = buildings_[b];
      }
    }
    building_count_ = kept;
    if (building_count_ == buildings_.size()) {
      ++counters_.buildings_dropped_full;
      continue;
    }
    buildings_[building_count_++] = traced;
  }
}

bool BuildingFitter::fit_block(const BlockTracer::Block& block,
                               std::span<const std::uint32_t> members,
                               Building& building) noexcept {
  const double axis_rad = tracer_.long_axis(block, dominant_axis(members));
  to_pieces(members, axis_rad);
  merge_parallel_pieces();
  for (std::size_t p = 0; p < piece_count_; ++p) {
    const Piece& piece = pieces_[p];
    side_walls_[p] = {piece.axis, piece.level, piece.lo, piece.hi};
  }
  const BlockTracer::Outline outline =
      tracer_.outline(block, axis_rad, side_walls_.first(piece_count_));
  if (outline.size < 4) {
    return false;
  }
  Model model;
  model.shape = outline.size == 4   ? BuildingShape::kRect
                : outline.size == 6 ? BuildingShape::kL
                                    : BuildingShape::kUnknown;
  model.size = outline.size;
  std::copy_n(outline.corners.begin(), outline.size, model.corners.begin());
  building = Building{};
  building.shape = model.shape;
  for (std::size_t k = 0; k < model.size; ++k) {
    building.footprint_m[k] = from_frame(model.corners[k], axis_rad);
  }
  building.footprint_size = model.size;
  set_height(building);
  emit_walls(model, axis_rad, building);
  set_confidence(building);
  return true;
}

}  // namespace blockmap::buildings
