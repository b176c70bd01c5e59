#include "blockmap/planes/plane_merger.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <tuple>
#include <type_traits>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/planes/polygon.hpp"

namespace blockmap::planes {
namespace {

// A small plane inside a big plane's noise slab (within_noise_slab): at most this share of
// the big plane's points, at most this far off its direction, and within this many of their
// summed RMS distances (plus merge_distance_m). A fragment of a blurred wall fitted on a
// hundred samples can be 15-20 deg off and still lie wholly in the slab: 15 deg left such
// fragments as walls of their own (usc_block with pose noise on a tilted world, and with a
// drifting error: PlaneRobustness.UscBlockWithPoseNoiseOnATiltedWorld).
constexpr double kSlabShareMax = 0.25;
constexpr double kSlabMaxAngleDeg = 25.0;
constexpr double kSlabPerRmse = 3.0;
// Two parallel planes are one when their offset is within merge_distance_m plus this many of
// their summed RMS distances: a slab blurred by pose errors can come back as two halves, each
// with its own least-squares plane a fraction of the slab apart. Crisp planes (RMS of a few
// millimetres) keep merge_distance_m.
constexpr double kOffsetPerRmse = 1.0;

double cos_deg(double degrees) {
  return std::cos(radians_from_degrees(degrees));
}
double sin_deg(double degrees) {
  return std::sin(radians_from_degrees(degrees));
}

bool boxes_within(const Eigen::Vector3d& a_min, const Eigen::Vector3d& a_max,
                  const Eigen::Vector3d& b_min, const Eigen::Vector3d& b_max, double gap) {
  return (a_min.array() - gap <= b_max.array()).all() &&
         (b_min.array() - gap <= a_max.array()).all();
}

}  // namespace

void PlaneMerger::init(Arena& arena, const PlanesConfig& config) {
  config_ = config;
  planes_ = arena.allocate_array<SectionPlane>(config.max_patches, "planes.merger");
  parent_ = arena.allocate_array<std::uint32_t>(config.max_patches, "planes.merger");
  member_order_ = arena.allocate_array<std::uint32_t>(config.max_patches, "planes.merger");
  candidates_ = arena.allocate_array<Candidate>(config.max_planes, "planes.merger");
  // Every corner of every section plane of one candidate, and two polygons side by side.
  scratch_points_ = arena.allocate_array<Eigen::Vector3d>(4 * config.max_patches, "planes.merger");
  scratch_2d_ = arena.allocate_array<Eigen::Vector2d>(4 * config.max_patches + 1, "planes.merger");
  scratch_hull_ =
      arena.allocate_array<Eigen::Vector2d>(4 * config.max_patches + 1, "planes.merger");
  scratch_other_ = arena.allocate_array<Eigen::Vector2d>(msg::kMaxPolygonVertices, "planes.merger");
  output_ = arena.allocate_array<msg::PlanePatch>(config.max_planes, "planes.merger");
  output_moments_ = arena.allocate_array<PointMoments>(config.max_planes, "planes.merger");
  clear();
}

std::size_t PlaneMerger::arena_bytes(const PlanesConfig& config) noexcept {
  constexpr std::size_t kAlignment = Arena::kMaxPaddingBytes;
  const std::size_t patches = config.max_patches;
  const std::size_t planes = config.max_planes;
  return patches * (sizeof(SectionPlane) + 2 * sizeof(std::uint32_t)) +
         planes * (sizeof(Candidate) + sizeof(msg::PlanePatch) + sizeof(PointMoments)) +
         4 * patches * sizeof(Eigen::Vector3d) + 2 * (4 * patches + 1) * sizeof(Eigen::Vector2d) +
         msg::kMaxPolygonVertices * sizeof(Eigen::Vector2d) + 10 * kAlignment;
}

void PlaneMerger::clear() noexcept {
  plane_count_ = 0;
  candidate_count_ = 0;
  output_count_ = 0;
  counters_ = Counters{};
}

bool PlaneMerger::add(const SectionPlane& plane) noexcept {
  if (plane_count_ == planes_.size()) {
    ++counters_.section_planes_dropped_full;
    return false;
  }
  BLOCKMAP_CHECK_MSG(plane_count_ == 0 || planes_[plane_count_ - 1].section <= plane.section,
                     "section planes must come in section order");
  parent_[plane_count_] = static_cast<std::uint32_t>(plane_count_);
  planes_[plane_count_++] = plane;
  return true;
}

std::uint32_t PlaneMerger::find_root(std::uint32_t i) noexcept {
  while (parent_[i] != i) {
    parent_[i] = parent_[parent_[i]];  // path halving
    i = parent_[i];
  }
  return i;
}

void PlaneMerger::join_neighbouring_section_planes() noexcept {
  const double cos_angle = cos_deg(config_.merge_angle_deg);
  const auto same_plane = [&](const SectionPlane& a, const SectionPlane& b) {
    if (std::abs(a.normal_unit.dot(b.normal_unit)) < cos_angle) {
      return false;
    }
    const Eigen::Vector3d ca = a.moments.mean();
    const Eigen::Vector3d cb = b.moments.mean();
    return std::abs(a.normal_unit.dot(cb) - a.d_m) <= config_.merge_distance_m &&
           std::abs(b.normal_unit.dot(ca) - b.d_m) <= config_.merge_distance_m;
  };
  // The planes are in section order, and a neighbouring section's key is the section's plus
  // a fixed offset (the packed coordinates have room): per offset, one cursor that only moves
  // forward finds the neighbour's planes, instead of a binary search per plane and offset.
  const std::span<const CellKey, 13> offsets = SectionGrid::later_neighbour_offsets();
  std::array<std::size_t, 13> cursor{};
  for (std::size_t i = 0; i < plane_count_; ++i) {
    for (std::size_t k = 0; k < offsets.size(); ++k) {
      const CellKey neighbour = planes_[i].section + offsets[k];
      std::size_t& at = cursor[k];
      while (at < plane_count_ && planes_[at].section < neighbour) {
        ++at;
      }
      for (std::size_t j = at; j < plane_count_ && planes_[j].section == neighbour; ++j) {
        if (same_plane(planes_[i], planes_[j])) {
          const std::uint32_t a = find_root(static_cast<std::uint32_t>(i));
          const std::uint32_t b = find_root(static_cast<std::uint32_t>(j));
          parent_[std::max(a, b)] = std::min(a, b);
        }
      }
    }
  }
}

void PlaneMerger::set_polygon(Candidate& candidate,
                              std::span<const Eigen::Vector3d> points) noexcept {
  const auto [u, v] = plane_basis(candidate.fit.normal_unit);
  const Eigen::Vector3d origin = candidate.fit.centroid_m;
  const std::size_t n = std::min(points.size(), scratch_2d_.size());
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d local = points[i] - origin;
    scratch_2d_[i] = Eigen::Vector2d(u.dot(local), v.dot(local));
  }
  std::size_t size = convex_hull(scratch_2d_.first(n), scratch_hull_);
  size = simplify_polygon(scratch_hull_, size, msg::kMaxPolygonVertices);
  candidate.polygon_size = static_cast<std::uint8_t>(size);
  candidate.box_min_m = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  candidate.box_max_m = -candidate.box_min_m;
  for (std::size_t i = 0; i < size; ++i) {
    const Eigen::Vector3d p = origin + scratch_hull_[i].x() * u + scratch_hull_[i].y() * v;
    candidate.polygon_m[i] = p;
    candidate.box_min_m = candidate.box_min_m.cwiseMin(p);
    candidate.box_max_m = candidate.box_max_m.cwiseMax(p);
  }
}

void PlaneMerger::build_candidates() noexcept {
  for (std::size_t i = 0; i < plane_count_; ++i) {
    member_order_[i] = static_cast<std::uint32_t>(i);
    find_root(static_cast<std::uint32_t>(i));
  }
  std::sort(member_order_.begin(),
            member_order_.begin() + static_cast<std::ptrdiff_t>(plane_count_),
            [this](std::uint32_t a, std::uint32_t b) {
              return parent_[a] != parent_[b] ? parent_[a] < parent_[b] : a < b;
            });
  candidate_count_ = 0;
  for (std::size_t i = 0; i < plane_count_;) {
    const std::uint32_t root = parent_[member_order_[i]];
    Candidate candidate;
    std::size_t corners = 0;
    for (; i < plane_count_ && parent_[member_order_[i]] == root; ++i) {
      const SectionPlane& plane = planes_[member_order_[i]];
      candidate.moments.merge(plane.moments);
      if (plane.section == kStepSection) {
        add_step_normal(candidate, plane.normal_unit, plane.moments.weight);
      }
      for (const Eigen::Vector3f& corner : plane.corners_m) {
        scratch_points_[corners++] = corner.cast<double>();
      }
    }
    if (candidate_count_ == candidates_.size()) {
      ++counters_.planes_dropped_full;
      continue;
    }
    candidate.fit = fit_candidate(candidate);
    if (!candidate.fit.valid) {
      continue;
    }
    set_polygon(candidate, scratch_points_.first(corners));
    candidates_[candidate_count_++] = candidate;
  }
}

bool PlaneMerger::can_merge(const Candidate& big, const Candidate& small) noexcept {
  const double reach_m =
      config_.merge_gap_m + config_.merge_gap_fraction * (big.box_max_m - big.box_min_m).norm();
  if (!boxes_within(big.box_min_m, big.box_max_m, small.box_min_m, small.box_max_m, reach_m)) {
    return false;
  }
  const Eigen::Vector3d& n = big.fit.normal_unit;
  const bool inside_slab = within_noise_slab(big, small);
  if (!inside_slab && std::abs(n.dot(small.fit.normal_unit)) < cos_deg(config_.merge_angle_deg)) {
    return false;
  }
  // The smaller plane's centroid lies on the bigger plane, within their noise.
  const double offset_m =
      config_.merge_distance_m + kOffsetPerRmse * (noise_rmse_m(big) + noise_rmse_m(small));
  if (!inside_slab && std::abs(n.dot(small.fit.centroid_m) - big.fit.d_m) > offset_m) {
    return false;
  }
  const std::pair<Eigen::Vector3d, Eigen::Vector3d> basis = plane_basis(n);
  const Eigen::Vector3d& u = basis.first;
  const Eigen::Vector3d& v = basis.second;
  const auto project = [&](const Candidate& c, std::span<Eigen::Vector2d> out) {
    for (std::size_t i = 0; i < c.polygon_size; ++i) {
      const Eigen::Vector3d local = c.polygon_m[i] - big.fit.centroid_m;
      out[i] = Eigen::Vector2d(u.dot(local), v.dot(local));
    }
    return out.first(c.polygon_size);
  };
  const auto a = project(big, scratch_hull_);
  const auto b = project(small, scratch_other_);
  // As Tavares and Padilha bridge longer gaps between longer segments, a plane bridges gaps up
  // to a fraction of its own size: occlusions (trees before a wall) leave holes that scale
  // with the wall, not with a fixed distance.
  return convex_polygon_gap(a, b) <= reach_m;
}

double PlaneMerger::noise_rmse_m(const Candidate& c) const noexcept {
  // A level laser's trace spans no height to tell a blurred slab from parallel things a few
  // decimetres apart (a kerb, a fence and the wall behind them): its spread is not noise.
  return config_.walls_from_lines ? 0.0 : c.fit.rmse_m;
}

bool PlaneMerger::within_noise_slab(const Candidate& big, const Candidate& small) const noexcept {
  // A wall blurred by pose errors is a slab a few RMS distances thick; the detector takes
  // its core, and the thin tails on either side come back as small planes, parallel or a
  // few degrees off, that lie wholly inside the slab. They are points of the big plane.
  if (small.moments.weight > kSlabShareMax * big.moments.weight ||
      std::abs(big.fit.normal_unit.dot(small.fit.normal_unit)) < cos_deg(kSlabMaxAngleDeg)) {
    return false;
  }
  // The small plane's own RMS counts too: a shoulder of the slab is a noisy plane itself.
  const double slab_m =
      kSlabPerRmse * (big.fit.rmse_m + noise_rmse_m(small)) + config_.merge_distance_m;
  for (std::size_t i = 0; i < small.polygon_size; ++i) {
    if (std::abs(big.fit.normal_unit.dot(small.polygon_m[i]) - big.fit.d_m) > slab_m) {
      return false;
    }
  }
  return small.polygon_size > 0;
}

void PlaneMerger::absorb(Candidate& big, const Candidate& small) noexcept {
  big.moments.merge(small.moments);
  if (small.step_weight > 0.0) {
    add_step_normal(big, small.step_normal_sum.normalized(), small.step_weight);
  }
  big.fit = fit_candidate(big);
  std::size_t n = 0;
  for (std::size_t i = 0; i < big.polygon_size; ++i) {
    scratch_points_[n++] = big.polygon_m[i];
  }
  for (std::size_t i = 0; i < small.polygon_size; ++i) {
    scratch_points_[n++] = small.polygon_m[i];
  }
  set_polygon(big, scratch_points_.first(n));
  ++counters_.stage2_merges;
}

std::size_t PlaneMerger::merge_candidates() noexcept {
  std::span<std::uint32_t> order = member_order_.first(candidate_count_);
  for (std::size_t i = 0; i < candidate_count_; ++i) {
    order[i] = static_cast<std::uint32_t>(i);
  }
  const auto by_support = [this](std::uint32_t a, std::uint32_t b) {
    const double wa = candidates_[a].moments.weight;
    const double wb = candidates_[b].moments.weight;
    return wa != wb ? wa > wb : a < b;
  };
  constexpr int kMaxPasses = 4;
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    std::sort(order.begin(), order.end(), by_support);
    bool merged = false;
    for (std::size_t i = 1; i < order.size(); ++i) {
      Candidate& small = candidates_[order[i]];
      if (!small.alive) {
        continue;
      }
      for (std::size_t j = 0; j < i; ++j) {
        Candidate& big = candidates_[order[j]];
        if (big.alive && can_merge(big, small)) {
          absorb(big, small);
          small.alive = false;
          merged = true;
          break;
        }
      }
    }
    if (!merged) {
      break;
    }
  }
  return static_cast<std::size_t>(std::count_if(
      order.begin(), order.end(), [this](std::uint32_t i) { return candidates_[i].alive; }));
}

void PlaneMerger::set_exclusions(std::span<const PlaneExclusion> exclusions) noexcept {
  exclusion_count_ = std::min(exclusions.size(), exclusions_.size());
  std::copy_n(exclusions.begin(), exclusion_count_, exclusions_.begin());
}

bool PlaneMerger::excluded(const Candidate& c) const noexcept {
  return excluded(c.fit.normal_unit, c.fit.d_m);
}

bool PlaneMerger::excluded(const Eigen::Vector3d& normal_unit, double d_m) const noexcept {
  for (std::size_t k = 0; k < exclusion_count_; ++k) {
    const PlaneExclusion& e = exclusions_[k];
    if (std::abs(normal_unit.dot(e.normal)) < e.cos_max_angle) {
      continue;
    }
    for (const Eigen::Vector3d& origin : e.origins_m) {
      if (std::abs(normal_unit.dot(origin) - d_m) <= e.distance_m) {
        return true;
      }
    }
  }
  return false;
}

void PlaneMerger::add_step_normal(Candidate& candidate, const Eigen::Vector3d& normal_unit,
                                  double weight) noexcept {
  const double sign = candidate.step_normal_sum.dot(normal_unit) < 0.0 ? -1.0 : 1.0;
  candidate.step_normal_sum += sign * weight * normal_unit;
  candidate.step_weight += weight;
}

PlaneFit PlaneMerger::fit_candidate(const Candidate& candidate) const noexcept {
  // Steps hold most of its points: it runs parallel to the walls they stepped back from (the
  // direction of their normals seen from above), its lean fitted.
  const Eigen::Vector3d along = Eigen::Vector3d::UnitZ().cross(candidate.step_normal_sum);
  if (candidate.step_weight >= kStepShareMin * candidate.moments.weight && along.norm() > 0.0) {
    return fit_plane_along_axis(candidate.moments, along.normalized());
  }
  return fit_of(candidate.moments);
}

PlaneFit PlaneMerger::fit_of(const PointMoments& moments) const noexcept {
  return config_.walls_from_lines ? fit_plane_or_wall(moments, 0.5 * config_.sample_size_m)
                                  : fit_plane(moments);
}

void PlaneMerger::drop_excluded() noexcept {
  for (std::size_t i = 0; i < candidate_count_; ++i) {
    Candidate& c = candidates_[i];
    if (c.alive && excluded(c)) {
      c.alive = false;
      ++counters_.planes_excluded;
    }
  }
}

void PlaneMerger::label_and_emit() noexcept {
  Candidate* ground = find_ground();
  if (ground != nullptr) {
    absorb_far_ground(*ground);
  }
  emit(ground);
  // Largest first, numbered from 1.
  std::sort(output_.begin(), output_.begin() + static_cast<std::ptrdiff_t>(output_count_),
            [](const msg::PlanePatch& a, const msg::PlanePatch& b) {
              if (a.support != b.support) {
                return a.support > b.support;
              }
              return std::tie(a.centroid_m.x(), a.centroid_m.y(), a.centroid_m.z()) <
                     std::tie(b.centroid_m.x(), b.centroid_m.y(), b.centroid_m.z());
            });
  for (std::size_t i = 0; i < output_count_; ++i) {
    output_moments_[i] = candidates_[output_[i].id].moments;
    output_[i].id = static_cast<std::uint32_t>(i + 1);
  }
}

bool PlaneMerger::horizontal(const Candidate& c) const noexcept {
  return std::abs(c.fit.normal_unit.z()) >= cos_deg(config_.label_tolerance_deg);
}

double PlaneMerger::height_above(const Candidate& ground, const Eigen::Vector3d& p) noexcept {
  const Eigen::Vector3d& n = ground.fit.normal_unit;
  const double ground_z = (ground.fit.d_m - n.x() * p.x() - n.y() * p.y()) / n.z();
  return p.z() - ground_z;
}

PlaneMerger::Candidate* PlaneMerger::find_ground() noexcept {
  // The lowest horizontal plane with at least a quarter of the largest one's points.
  const std::span<const std::uint32_t> order = member_order_.first(candidate_count_);
  double largest_horizontal = 0.0;
  for (const std::uint32_t i : order) {
    const Candidate& c = candidates_[i];
    if (c.alive && horizontal(c)) {
      largest_horizontal = std::max(largest_horizontal, c.moments.weight);
    }
  }
  Candidate* ground = nullptr;
  for (const std::uint32_t i : order) {
    Candidate& c = candidates_[i];
    if (c.alive && horizontal(c) && c.moments.weight >= 0.25 * largest_horizontal &&
        (ground == nullptr || c.fit.centroid_m.z() < ground->fit.centroid_m.z())) {
      ground = &c;
    }
  }
  return ground;
}

void PlaneMerger::absorb_far_ground(Candidate& ground) noexcept {
  // The ground is one surface under everything: far pieces of it, cut off from the rest by
  // buildings or by the reach of the lasers, are merged into it however far away they lie.
  for (const std::uint32_t i : member_order_.first(candidate_count_)) {
    Candidate& c = candidates_[i];
    if (c.alive && &c != &ground && horizontal(c) &&
        std::abs(height_above(ground, c.fit.centroid_m)) <= config_.ground_step_m) {
      absorb(ground, c);
      c.alive = false;
    }
  }
}

msg::PlaneKind PlaneMerger::kind_of(const Candidate& c, const Eigen::Vector3d& normal,
                                    const Candidate* ground) const noexcept {
  if (std::abs(normal.z()) <= sin_deg(config_.label_tolerance_deg)) {
    const auto [u, v] = plane_basis(normal);
    double u_min = 1e300, u_max = -1e300, z_min = 1e300, z_max = -1e300;
    for (std::size_t k = 0; k < c.polygon_size; ++k) {
      const double along = u.dot(c.polygon_m[k]);
      u_min = std::min(u_min, along);
      u_max = std::max(u_max, along);
      z_min = std::min(z_min, c.polygon_m[k].z());
      z_max = std::max(z_max, c.polygon_m[k].z());
    }
    // A wall seen as a line (walls_from_lines) has no observed height: its width decides.
    const bool big = (c.fit.from_line || z_max - z_min >= config_.min_wall_height_m) &&
                     u_max - u_min >= config_.min_wall_width_m;
    return big ? msg::PlaneKind::kWall : msg::PlaneKind::kOther;
  }
  if (std::abs(normal.z()) >= cos_deg(config_.label_tolerance_deg) && ground != nullptr) {
    const double height = height_above(*ground, c.fit.centroid_m);
    return std::abs(height) <= config_.ground_step_m ? msg::PlaneKind::kGround
           : height >= config_.min_roof_height_m     ? msg::PlaneKind::kRoof
                                                     : msg::PlaneKind::kOther;
  }
  return msg::PlaneKind::kOther;
}

void PlaneMerger::emit(const Candidate* ground) noexcept {
  output_count_ = 0;
  for (const std::uint32_t i : member_order_.first(candidate_count_)) {
    const Candidate& c = candidates_[i];
    if (!c.alive || c.moments.weight < config_.min_reported_support) {
      continue;
    }
    msg::PlanePatch plane;
    Eigen::Vector3d n = c.fit.normal_unit;
    double d = c.fit.d_m;
    if ((std::abs(n.z()) >= 0.5 && n.z() < 0.0) || (std::abs(n.z()) < 0.5 && d < 0.0)) {
      n = -n;  // up for horizontal planes, away from the frame's origin for the others
      d = -d;
    }
    plane.kind = kind_of(c, n, ground);
    plane.normal = n;
    plane.d_m = d;
    plane.support = c.moments.weight;
    plane.rmse_m = c.fit.rmse_m;
    plane.centroid_m = c.fit.centroid_m;
    plane.polygon_size = c.polygon_size;
    std::copy(c.polygon_m.begin(), c.polygon_m.begin() + c.polygon_size, plane.polygon_m.begin());
    plane.id = i;  // the candidate, until the planes are numbered below
    output_[output_count_++] = plane;
  }
}

std::span<const msg::PlanePatch> PlaneMerger::merge() noexcept {
  // A merge may run again after more section planes came (the corner look): it counts anew.
  counters_.planes_dropped_full = 0;
  counters_.stage2_merges = 0;
  counters_.planes_excluded = 0;
  join_neighbouring_section_planes();
  build_candidates();
  merge_candidates();
  drop_excluded();
  label_and_emit();
  return output_.first(output_count_);
}

std::size_t PlaneMerger::memory_bytes() const noexcept {
  return planes_.size_bytes() + parent_.size_bytes() + member_order_.size_bytes() +
         candidates_.size_bytes() + scratch_points_.size_bytes() + scratch_2d_.size_bytes() +
         scratch_hull_.size_bytes() + scratch_other_.size_bytes() + output_.size_bytes() +
         output_moments_.size_bytes();
}

}  // namespace blockmap::planes
