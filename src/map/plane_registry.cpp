#include "blockmap/map/plane_registry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/planes/polygon.hpp"
#include "plane_extent.hpp"

namespace blockmap::map {
namespace {

// Whether `meet_at` holds at the two polygons' vertices nearest each other. A facade that a
// level laser saw through drifting poses comes in long traces a degree or two apart: their
// centroids, tens of metres from each other, lie off each other's line by that angle times
// their distance, while the traces meet where one ends and the next begins.
template <typename MeetAt>
bool meet_at_nearest_ends(const msg::PlanePatch& known, const msg::PlanePatch& detected,
                          const MeetAt& meet_at) noexcept {
  const Eigen::Vector3d* known_end = nullptr;
  const Eigen::Vector3d* detected_end = nullptr;
  double nearest_m2 = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& a : polygon_of(known)) {
    for (const Eigen::Vector3d& b : polygon_of(detected)) {
      if ((a - b).squaredNorm() < nearest_m2) {
        nearest_m2 = (a - b).squaredNorm();
        known_end = &a;
        detected_end = &b;
      }
    }
  }
  return known_end != nullptr && meet_at(*known_end, *detected_end);
}

// A voxel's sums as moments about the frame's origin.
planes::PointMoments sample_moments(const planes::VoxelSums& sums, double voxel_size_m) noexcept {
  return planes::VoxelGrid::moments_of(sums, voxel_size_m, Eigen::Vector3d::Zero());
}

// Between two begin_update(): each plane live before it leaves at most once (finalized,
// merged or removed) and is changed at most once; each detected plane adds at most one plane
// and pushes out at most one when the registry is full.
// The end of a run with a rigid path is one update: each live plane finalized (at most
// max_live_planes), then each final plane moved once (move_finals_by, at most
// max_final_planes). A refreshed view reports each plane at most once, in updates of its own
// (refresh_view).
// What is beyond that bound (final planes joining a live one, or dropped from a full list)
// is kExtraChangesPerUpdate at most, on top.
std::size_t changes_per_update(const PlaneRegistryConfig& config) noexcept {
  return std::max(2 * (config.max_live_planes + config.max_detected_planes),
                  config.max_live_planes + config.max_final_planes) +
         PlaneRegistry::kExtraChangesPerUpdate;
}

}  // namespace

std::string validate(const PlaneRegistryConfig& config) {
  if (config.max_live_planes < 1 || config.max_final_planes < 1 ||
      config.max_live_planes > (std::size_t{1} << 20) ||
      config.max_final_planes > (std::size_t{1} << 24)) {
    return "registry: max_live_planes (1 to 2^20) and max_final_planes (1 to 2^24) are needed";
  }
  if (!(config.match_angle_deg > 0.0 && config.match_angle_deg < 90.0) ||
      !(config.match_distance_m > 0.0) || !(config.match_gap_m >= 0.0)) {
    return "registry: match_angle_deg (0-90), match_distance_m (> 0) and match_gap_m (>= 0)";
  }
  if (config.retract_after_misses < 1 || !(config.min_final_support >= 0.0)) {
    return "registry: retract_after_misses must be at least 1, min_final_support not negative";
  }
  if (!(config.band_m > 0.0) || !(config.max_band_m >= config.band_m)) {
    return "registry: band_m must be positive and at most max_band_m";
  }
  if (!(config.change_angle_deg >= 0.0) || !(config.change_offset_m >= 0.0) ||
      !(config.change_support_ratio >= 0.0) || !(config.change_extent_m >= 0.0)) {
    return "registry: the change thresholds must not be negative";
  }
  return {};
}

void SeenSpans::add_span(TimestampNs from, TimestampNs to) noexcept {
  // The spans it comes within kJoinGapNs of join it.
  for (std::size_t i = 0; i < count;) {
    if (from <= to_ns[i] + kJoinGapNs && to + kJoinGapNs >= from_ns[i]) {
      from = std::min(from, from_ns[i]);
      to = std::max(to, to_ns[i]);
      --count;
      from_ns[i] = from_ns[count];
      to_ns[i] = to_ns[count];
      continue;
    }
    ++i;
  }
  if (count == kMaxSpans) {
    // Full: the two spans nearest in time (the new one among them) become one.
    std::array<TimestampNs, kMaxSpans + 1> all_from{};
    std::array<TimestampNs, kMaxSpans + 1> all_to{};
    std::copy(from_ns.begin(), from_ns.end(), all_from.begin());
    std::copy(to_ns.begin(), to_ns.end(), all_to.begin());
    all_from[kMaxSpans] = from;
    all_to[kMaxSpans] = to;
    std::size_t a = 0;
    std::size_t b = 1;
    TimestampNs shortest = std::numeric_limits<TimestampNs>::max();
    for (std::size_t i = 0; i <= kMaxSpans; ++i) {
      for (std::size_t j = i + 1; j <= kMaxSpans; ++j) {
        const TimestampNs gap = std::max(all_from[i], all_from[j]) - std::min(all_to[i], all_to[j]);
        if (gap < shortest) {
          shortest = gap;
          a = i;
          b = j;
        }
      }
    }
    all_from[a] = std::min(all_from[a], all_from[b]);
    all_to[a] = std::max(all_to[a], all_to[b]);
    all_from[b] = all_from[kMaxSpans];
    all_to[b] = all_to[kMaxSpans];
    std::copy_n(all_from.begin(), kMaxSpans, from_ns.begin());
    std::copy_n(all_to.begin(), kMaxSpans, to_ns.begin());
    return;
  }
  from_ns[count] = from;
  to_ns[count] = to;
  ++count;
}

void SeenSpans::merge(const SeenSpans& other) noexcept {
  for (std::size_t i = 0; i < other.count; ++i) {
    add_span(other.from_ns[i], other.to_ns[i]);
  }
}

bool SeenSpans::covers(TimestampNs stamp_ns, TimestampNs lead_ns) const noexcept {
  for (std::size_t i = 0; i < count; ++i) {
    if (stamp_ns + lead_ns >= from_ns[i] && stamp_ns <= to_ns[i]) {
      return true;
    }
  }
  return false;
}

void PlaneRegistry::init(Arena& arena, const PlaneRegistryConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), "an invalid registry configuration reached init()");
  config_ = config;
  cos_match_angle_ = std::cos(config.match_angle_deg * kRadiansPerDegree);
  cos_change_angle_ = std::cos(config.change_angle_deg * kRadiansPerDegree);
  live_ = arena.allocate_array<LivePlane>(config.max_live_planes, "registry.live");
  final_ = arena.allocate_array<msg::PlanePatch>(config.max_final_planes, "registry.final");
  final_moments_ =
      arena.allocate_array<planes::PointMoments>(config.max_final_planes, "registry.final");
  final_seen_ = arena.allocate_array<SeenSpans>(config.max_final_planes, "registry.final");
  final_shown_ = arena.allocate_array<PlaneMove>(config.max_final_planes, "registry.final");
  changes_ = arena.allocate_array<msg::PlaneChange>(changes_per_update(config), "registry.changes");
  constexpr std::size_t kPoints = VoxelWindow::kEvictionChunk + 2 * msg::kMaxPolygonVertices;
  scratch_2d_ = arena.allocate_array<Eigen::Vector2d>(kPoints, "registry.scratch");
  scratch_hull_ = arena.allocate_array<Eigen::Vector2d>(kPoints + 1, "registry.scratch");
}

std::size_t PlaneRegistry::arena_bytes(const PlaneRegistryConfig& config) noexcept {
  constexpr std::size_t kPoints = VoxelWindow::kEvictionChunk + 2 * msg::kMaxPolygonVertices;
  return config.max_live_planes * sizeof(LivePlane) +
         config.max_final_planes * (sizeof(msg::PlanePatch) + sizeof(planes::PointMoments) +
                                    sizeof(SeenSpans) + sizeof(PlaneMove)) +
         changes_per_update(config) * sizeof(msg::PlaneChange) +
         (2 * kPoints + 1) * sizeof(Eigen::Vector2d) + std::size_t{6} * 64;
}

std::uint8_t PlaneRegistry::hull_on_plane(const Eigen::Vector3d& normal,
                                          const Eigen::Vector3d& centroid,
                                          std::span<const Eigen::Vector3d> a,
                                          std::span<const Eigen::Vector3d> b,
                                          std::span<Eigen::Vector3d> out) noexcept {
  const auto [u, v] = planes::plane_basis(normal);
  std::size_t n = 0;
  for (const std::span<const Eigen::Vector3d> points : {a, b}) {
    for (const Eigen::Vector3d& p : points) {
      if (n < scratch_2d_.size()) {
        scratch_2d_[n++] = Eigen::Vector2d(u.dot(p - centroid), v.dot(p - centroid));
      }
    }
  }
  std::size_t size = planes::convex_hull(scratch_2d_.first(n), scratch_hull_);
  size = planes::simplify_polygon(scratch_hull_, size, msg::kMaxPolygonVertices);
  for (std::size_t i = 0; i < size; ++i) {
    out[i] = centroid + scratch_hull_[i].x() * u + scratch_hull_[i].y() * v;
  }
  return static_cast<std::uint8_t>(size);
}

void PlaneRegistry::on_evicted(const VoxelWindow::EvictedTile& tile) noexcept {
  for (LivePlane& plane : live_) {
    if (!plane.in_use || plane.reported.id == 0) {
      continue;
    }
    const msg::PlanePatch& reported = plane.reported;
    const double band = std::clamp(3.0 * reported.rmse_m, config_.band_m, config_.max_band_m);
    Eigen::AlignedBox3d reach = plane.box_m();
    reach.min().array() -= band;
    reach.max().array() += band;
    const Eigen::AlignedBox2d reach_2d(reach.min().head<2>(), reach.max().head<2>());
    if (!reach_2d.intersects(tile.bounds_m)) {
      continue;
    }
    // The samples on this plane: their moments freeze, and their centroids (with the frozen
    // polygon's vertices) give its extent.
    const std::pair<Eigen::Vector3d, Eigen::Vector3d> basis = planes::plane_basis(reported.normal);
    const auto on_plane = [&basis, &reported](const Eigen::Vector3d& p) {
      const Eigen::Vector3d offset = p - reported.centroid_m;
      return Eigen::Vector2d(basis.first.dot(offset), basis.second.dot(offset));
    };
    std::size_t n = 0;
    for (std::size_t i = 0; i < plane.frozen_polygon_size; ++i) {
      scratch_2d_[n++] = on_plane(plane.frozen_polygon_m[i]);
    }
    std::size_t kept = 0;
    for (const planes::VoxelSums& sums : tile.samples) {
      if (sums.point_count == 0) {
        continue;
      }
      const planes::PointMoments moments = sample_moments(sums, tile.voxel_size_m);
      const Eigen::Vector3d centroid = moments.mean();
      if (std::abs(reported.normal.dot(centroid) - reported.d_m) > band ||
          !reach.contains(centroid)) {
        continue;
      }
      plane.frozen.merge(moments);
      scratch_2d_[n++] = on_plane(centroid);  // room: a chunk plus a polygon
      ++kept;
    }
    if (kept == 0) {
      continue;
    }
    std::size_t size = planes::convex_hull(scratch_2d_.first(n), scratch_hull_);
    size = planes::simplify_polygon(scratch_hull_, size, msg::kMaxPolygonVertices);
    for (std::size_t i = 0; i < size; ++i) {
      plane.frozen_polygon_m[i] = reported.centroid_m + scratch_hull_[i].x() * basis.first +
                                  scratch_hull_[i].y() * basis.second;
    }
    plane.frozen_polygon_size = static_cast<std::uint8_t>(size);
    plane.fresh = false;  // its live points include some of these until the next detection
    counters_.samples_frozen += kept;
  }
}

bool PlaneRegistry::matches(const msg::PlanePatch& known, const Eigen::AlignedBox3d& known_box,
                            const msg::PlanePatch& detected,
                            const Eigen::AlignedBox3d& detected_box, double gap_m) const noexcept {
  if (std::abs(known.normal.dot(detected.normal)) < cos_match_angle_) {
    return false;
  }
  const double tolerance =
      std::max(config_.match_distance_m, 2.0 * std::max(known.rmse_m, detected.rmse_m));
  // Each plane passes within the tolerance of a point of the other: its centroid, or (level
  // lasers' traces) the end nearest to it.
  const auto meet_at = [&](const Eigen::Vector3d& known_at, const Eigen::Vector3d& detected_at) {
    return std::abs(known.normal.dot(detected_at) - known.d_m) <= tolerance &&
           std::abs(detected.normal.dot(known_at) - detected.d_m) <= tolerance;
  };
  if (!meet_at(known.centroid_m, detected.centroid_m) &&
      !(config_.walls_from_lines && meet_at_nearest_ends(known, detected, meet_at))) {
    return false;
  }
  return known_box.exteriorDistance(detected_box) <= gap_m;
}

planes::PlaneFit PlaneRegistry::fit_of(const planes::PointMoments& points) const noexcept {
  return config_.walls_from_lines ? planes::fit_plane_or_wall(points, config_.line_width_m)
                                  : planes::fit_plane(points);
}

PlaneRegistry::LivePlane* PlaneRegistry::match_and_merge(const msg::PlanePatch& detected) noexcept {
  const Eigen::AlignedBox3d detected_box = box_of(polygon_of(detected));
  // Planes added by this update are not matched again: the detector merged the window.
  const auto candidate = [&](const LivePlane& plane) {
    return plane.in_use && plane.reported.id != 0 &&
           matches(plane.reported, plane.box_m(), detected, detected_box, config_.match_gap_m);
  };
  LivePlane* biggest = nullptr;
  for (LivePlane& plane : live_) {
    if (candidate(plane) &&
        (biggest == nullptr || plane.reported.support > biggest->reported.support)) {
      biggest = &plane;
    }
  }
  if (biggest == nullptr) {
    // Not live: perhaps a final plane the robot has come back to.
    return take_final_matches(detected, detected_box, nullptr);
  }
  for (LivePlane& plane : live_) {
    if (&plane != biggest && candidate(plane)) {
      absorb(*biggest, plane);
    }
  }
  static_cast<void>(take_final_matches(detected, detected_box, biggest));
  return biggest;
}

PlaneRegistry::LivePlane* PlaneRegistry::take_final_matches(const msg::PlanePatch& detected,
                                                            const Eigen::AlignedBox3d& detected_box,
                                                            LivePlane* into) noexcept {
  for (std::size_t i = 0; i < final_count_;) {
    const msg::PlanePatch final_plane = final_[i];
    if (!matches(final_plane, box_of(polygon_of(final_plane)), detected, detected_box,
                 config_.match_gap_m)) {
      ++i;
      continue;
    }
    if (into != nullptr && !take_extra_change()) {
      ++i;  // no room in this update to report it removed: it joins at the next one
      continue;
    }
    const planes::PointMoments moments = final_moments_[i];
    const SeenSpans seen = final_seen_[i];
    const PlaneMove shown = final_shown_[i];
    remove_final(i);  // i now holds the next one
    if (into == nullptr) {
      LivePlane* slot = free_slot(final_plane.support);
      if (slot == nullptr) {
        // No room to reopen it: it stays final (in the place it just left).
        static_cast<void>(store_final(final_plane, moments, seen, shown));
        return nullptr;
      }
      *slot = LivePlane{};
      slot->in_use = true;
      ++live_count_;
      slot->kind = final_plane.kind;
      slot->kind_support = final_plane.support;
      slot->frozen = moments;
      slot->frozen_polygon_m = final_plane.polygon_m;
      slot->frozen_polygon_size = final_plane.polygon_size;
      slot->reference_normal = final_plane.normal;
      slot->reported = final_plane;
      slot->seen = seen;
      slot->shown = shown;
      const Eigen::AlignedBox3d box = box_of(polygon_of(final_plane));
      slot->box_min_m = box.min();
      slot->box_max_m = box.max();
      ++counters_.reopened;
      into = slot;
      continue;
    }
    // A second final plane on the same surface: one with the first.
    into->frozen.merge(moments);
    into->seen.merge(seen);
    std::array<Eigen::Vector3d, msg::kMaxPolygonVertices> joined{};
    into->frozen_polygon_size =
        hull_on_plane(into->reported.normal, into->reported.centroid_m,
                      {into->frozen_polygon_m.data(), into->frozen_polygon_size},
                      polygon_of(final_plane), joined);
    into->frozen_polygon_m = joined;
    emit(msg::PlaneChangeKind::kRemoved, final_plane, shown);
    ++counters_.merged;
  }
  return into;
}

bool PlaneRegistry::take_extra_change() noexcept {
  if (extra_changes_ == kExtraChangesPerUpdate) {
    return false;
  }
  ++extra_changes_;
  return true;
}

void PlaneRegistry::absorb(LivePlane& big, LivePlane& small) noexcept {
  big.frozen.merge(small.frozen);
  big.seen.merge(small.seen);
  if (small.kind_support > big.kind_support) {
    big.kind = small.kind;
    big.kind_support = small.kind_support;
  }
  std::array<Eigen::Vector3d, msg::kMaxPolygonVertices> joined{};
  if (small.frozen_polygon_size > 0) {
    const std::uint8_t size =
        hull_on_plane(big.reported.normal, big.reported.centroid_m,
                      {big.frozen_polygon_m.data(), big.frozen_polygon_size},
                      {small.frozen_polygon_m.data(), small.frozen_polygon_size}, joined);
    big.frozen_polygon_m = joined;
    big.frozen_polygon_size = size;
  }
  // What an earlier detection of this update gave the small one is the big one's too.
  if (small.matched_in == update_number_) {
    if (big.matched_in == update_number_) {
      big.live.merge(small.live);
      const std::uint8_t size = hull_on_plane(
          big.reference_normal, big.live.mean(), {big.live_polygon_m.data(), big.live_polygon_size},
          {small.live_polygon_m.data(), small.live_polygon_size}, joined);
      big.live_polygon_m = joined;
      big.live_polygon_size = size;
    } else {
      big.matched_in = update_number_;
      big.live = small.live;
      big.live_polygon_m = small.live_polygon_m;
      big.live_polygon_size = small.live_polygon_size;
      big.reference_normal = small.reference_normal;
    }
    big.fresh = true;
  }
  ++counters_.merged;
  remove(small);
}

void PlaneRegistry::remove(LivePlane& plane) noexcept {
  emit(msg::PlaneChangeKind::kRemoved, plane.reported, plane.shown);
  plane.in_use = false;
  --live_count_;
}

void PlaneRegistry::count_misses() noexcept {
  for (LivePlane& plane : live_) {
    if (!plane.in_use || plane.reported.id == 0) {
      continue;
    }
    if (plane.matched_in == update_number_) {
      plane.misses = 0;
      continue;
    }
    plane.fresh = false;
    if (++plane.misses < config_.retract_after_misses) {
      continue;
    }
    if (plane.frozen.weight >= config_.min_final_support) {
      finalize(plane);  // what left the window while it was seen stays in the map
    } else {
      ++counters_.retracted;
      remove(plane);
    }
  }
}

PlaneRegistry::LivePlane* PlaneRegistry::free_slot(double support) noexcept {
  if (live_count_ < live_.size()) {
    for (LivePlane& plane : live_) {
      if (!plane.in_use) {
        return &plane;
      }
    }
  }
  LivePlane* smallest = nullptr;
  for (LivePlane& plane : live_) {
    if (plane.reported.id != 0 &&
        (smallest == nullptr || plane.reported.support < smallest->reported.support)) {
      smallest = &plane;
    }
  }
  if (smallest == nullptr || smallest->reported.support >= support) {
    ++counters_.refused_full;
    return nullptr;
  }
  ++counters_.finalized_early;
  finalize(*smallest);
  return smallest;
}

void PlaneRegistry::update(std::span<const msg::PlanePatch> detected,
                           std::span<const planes::PointMoments> moments,
                           TimestampNs seen_ns) noexcept {
  BLOCKMAP_CHECK_MSG(detected.size() == moments.size(), "each detected plane needs its moments");
  ++update_number_;
  for (std::size_t i = 0; i < detected.size(); ++i) {
    const msg::PlanePatch& seen = detected[i];
    LivePlane* plane = match_and_merge(seen);
    if (plane == nullptr) {
      plane = free_slot(seen.support);
      if (plane == nullptr) {
        continue;
      }
      *plane = LivePlane{};
      plane->in_use = true;
      ++live_count_;
    }
    if (plane->matched_in != update_number_) {
      // The first look at it in this detection: the live part is replaced.
      plane->matched_in = update_number_;
      plane->live = moments[i];
      plane->live_polygon_size = seen.polygon_size;
      std::copy_n(seen.polygon_m.begin(), seen.polygon_size, plane->live_polygon_m.begin());
      plane->reference_normal = seen.normal;
    } else {
      // More of it (the detector saw two pieces that the map knows are one).
      plane->live.merge(moments[i]);
      std::array<Eigen::Vector3d, msg::kMaxPolygonVertices> joined{};
      const std::uint8_t size = hull_on_plane(
          plane->reference_normal, plane->live.mean(),
          {plane->live_polygon_m.data(), plane->live_polygon_size}, polygon_of(seen), joined);
      plane->live_polygon_m = joined;
      plane->live_polygon_size = size;
    }
    plane->fresh = true;
    plane->seen.add(seen_ns);
    // The label of the best look: a window that holds a corner of a plane labels it by what
    // else it holds (the ground is the lowest large horizontal plane in it).
    if (seen.support >= plane->kind_support) {
      plane->kind = seen.kind;
      plane->kind_support = seen.support;
    }
  }
  count_misses();
  for (LivePlane& plane : live_) {
    if (!plane.in_use || plane.matched_in != update_number_) {
      continue;
    }
    if (plane.reported.id == 0) {
      plane.reported.id = next_id_++;
      report(plane, msg::PlaneChangeKind::kAdded);
      continue;
    }
    msg::PlanePatch now = plane.reported;
    combine(plane, now);
    if (differs(now, plane.reported)) {
      report(plane, msg::PlaneChangeKind::kChanged);
    }
  }
  counters_.peak_live = std::max(counters_.peak_live, live_count_);
}

planes::PointMoments PlaneRegistry::points_of(const LivePlane& plane) noexcept {
  planes::PointMoments points = plane.frozen;
  // A live part that is not fresh may hold points that have frozen since: left out, unless
  // it is all there is.
  if (plane.fresh || plane.frozen.weight == 0.0) {
    points.merge(plane.live);
  }
  return points;
}

void PlaneRegistry::combine(const LivePlane& plane, msg::PlanePatch& out) noexcept {
  const planes::PointMoments points = points_of(plane);
  const planes::PlaneFit fit = fit_of(points);
  if (!fit.valid) {
    return;
  }
  Eigen::Vector3d normal = fit.normal_unit;
  double d_m = fit.d_m;
  if (normal.dot(plane.reference_normal) < 0.0) {
    normal = -normal;
    d_m = -d_m;
  }
  out.kind = plane.kind;
  out.normal = normal;
  out.d_m = d_m;
  out.support = points.weight;
  out.rmse_m = fit.rmse_m;
  out.centroid_m = fit.centroid_m;
  out.polygon_size = hull_on_plane(
      normal, fit.centroid_m, {plane.frozen_polygon_m.data(), plane.frozen_polygon_size},
      {plane.live_polygon_m.data(), plane.live_polygon_size}, out.polygon_m);
}

bool PlaneRegistry::differs(const msg::PlanePatch& a, const msg::PlanePatch& b) const noexcept {
  if (a.normal.dot(b.normal) < cos_change_angle_ ||
      std::abs(a.d_m - b.d_m) > config_.change_offset_m ||
      std::abs(a.support - b.support) > config_.change_support_ratio * b.support ||
      a.kind != b.kind) {
    return true;
  }
  const Eigen::AlignedBox3d box_a = box_of(polygon_of(a));
  const Eigen::AlignedBox3d box_b = box_of(polygon_of(b));
  return (box_a.min() - box_b.min()).cwiseAbs().maxCoeff() > config_.change_extent_m ||
         (box_a.max() - box_b.max()).cwiseAbs().maxCoeff() > config_.change_extent_m;
}

void PlaneRegistry::report(LivePlane& plane, msg::PlaneChangeKind change) noexcept {
  combine(plane, plane.reported);
  const Eigen::AlignedBox3d box = box_of(polygon_of(plane.reported));
  plane.box_min_m = box.min();
  plane.box_max_m = box.max();
  plane.shown = view_move(plane.reported, plane.seen);
  emit(change, plane.reported, plane.shown);
  if (change == msg::PlaneChangeKind::kAdded) {
    ++counters_.added;
  } else if (change == msg::PlaneChangeKind::kChanged) {
    ++counters_.changed;
  }
}

void PlaneRegistry::emit(msg::PlaneChangeKind change, const msg::PlanePatch& plane,
                         const PlaneMove& shown) noexcept {
  // The capacity is what one update can produce (init()); more is a bug.
  BLOCKMAP_CHECK_MSG(change_count_ < changes_.size(), "more plane changes than one update holds");
  msg::PlaneChange& out = changes_[change_count_++];
  counters_.peak_changes = std::max(counters_.peak_changes, change_count_);
  out = msg::PlaneChange{change, plane};
  if (!shown.is_identity()) {
    move_plane(out.plane, shown);
  }
}

void PlaneRegistry::finalize(LivePlane& plane) noexcept {
  combine(plane, plane.reported);
  plane.shown = view_move(plane.reported, plane.seen);
  ++counters_.finalized;
  const bool kept = store_final(plane.reported, points_of(plane), plane.seen, plane.shown);
  // Left out of a full final list: the stream drops it too.
  emit(kept ? msg::PlaneChangeKind::kFinalized : msg::PlaneChangeKind::kRemoved, plane.reported,
       plane.shown);
  plane.in_use = false;
  --live_count_;
}

void PlaneRegistry::finalize_outside(const Eigen::AlignedBox2d& window_m) noexcept {
  for (LivePlane& plane : live_) {
    if (!plane.in_use || plane.reported.id == 0) {
      continue;
    }
    const Eigen::AlignedBox2d extent(plane.box_min_m.head<2>(), plane.box_max_m.head<2>());
    if (!extent.intersects(window_m)) {
      finalize(plane);
    }
  }
}

void PlaneRegistry::finalize_all() noexcept {
  for (LivePlane& plane : live_) {
    if (plane.in_use && plane.reported.id != 0) {
      finalize(plane);
    }
  }
}

}  // namespace blockmap::map
