// BuildingFitter's identities: a building keeps its id from one fit to the next through the
// wall planes it shares with a building of the last fit, else the one it overlaps most.
#include <algorithm>
#include <limits>

#include "blockmap/buildings/building_fitter.hpp"
#include "footprint.hpp"

namespace blockmap::buildings {

void BuildingFitter::init_past_set(Arena& arena, PastSet& set) const {
  const std::size_t remembered = 2 * config_.max_buildings;
  set.ids = arena.allocate_array<std::uint32_t>(remembered, "buildings.fitter");
  set.extents = arena.allocate_array<Extent>(remembered, "buildings.fitter");
  set.absent_fits = arena.allocate_array<std::uint16_t>(remembered, "buildings.fitter");
  set.planes = arena.allocate_array<PastPlane>(remembered * kMaxBuildingWalls, "buildings.fitter");
  set.count = 0;
  set.plane_count = 0;
}

std::size_t BuildingFitter::past_set_bytes(const BuildingsConfig& config) noexcept {
  const std::size_t remembered = 2 * config.max_buildings;
  return Arena::array_bytes<std::uint32_t>(remembered) + Arena::array_bytes<Extent>(remembered) +
         Arena::array_bytes<std::uint16_t>(remembered) +
         Arena::array_bytes<PastPlane>(remembered * kMaxBuildingWalls);
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

}  // namespace blockmap::buildings
