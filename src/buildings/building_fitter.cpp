#include "blockmap/buildings/building_fitter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "blockmap/core/angles.hpp"
#include "blockmap/planes/polygon.hpp"
#include "footprint.hpp"

namespace blockmap::buildings {

using footprint::from_frame;

namespace {

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

std::size_t BuildingFitter::arena_bytes(const BuildingsConfig& config,
                                        std::size_t free_space_cells) noexcept {
  const std::size_t remembered = 2 * config.max_buildings;
  const std::size_t blocks = free_space_cells == 0
                                 ? 0
                                 : BlockTracer::arena_bytes(config, free_space_cells) +
                                       Arena::array_bytes<std::uint32_t>(config.max_walls) +
                                       Arena::array_bytes<SideWall>(config.max_walls);
  return blocks + Arena::array_bytes<WallSegment>(config.max_walls) +
         2 * Arena::array_bytes<std::uint32_t>(config.max_walls) +
         Arena::array_bytes<Piece>(config.max_walls) + Arena::array_bytes<Roof>(config.max_walls) +
         Arena::array_bytes<Building>(config.max_buildings) + 2 * past_set_bytes(config) +
         Arena::array_bytes<std::uint8_t>(remembered) +
         2 * Arena::array_bytes<std::uint32_t>(remembered);
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
  ModelScore best_score;
  const Model& model = best_model(best_score);
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
    add_observed_walls(building);
    return true;
  }
  emit_walls(model, axis_rad, building);
  set_confidence(building);
  return true;
}

const BuildingFitter::Model& BuildingFitter::best_model(ModelScore& best_score) const noexcept {
  std::size_t best = 0;
  best_score = score(models_[0]);
  for (std::size_t m = 1; m < model_count_; ++m) {
    const ModelScore candidate = score(models_[m]);
    if (candidate.cost < best_score.cost) {
      best = m;
      best_score = candidate;
    }
  }
  return models_[best];
}

void BuildingFitter::add_observed_walls(Building& building) const noexcept {
  for (const Piece& piece : pieces_.first(piece_count_)) {
    if (building.wall_count == kMaxBuildingWalls) {
      break;
    }
    const WallSegment& segment = segments_[piece.segment];
    building.walls[building.wall_count++] = {segment.p0_m, segment.p1_m, segment.z0_m,
                                             segment.z1_m, false,        segment.plane_id};
  }
  building.confidence = 0.0;
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
