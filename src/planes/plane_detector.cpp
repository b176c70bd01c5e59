#include "blockmap/planes/plane_detector.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>

#include "blockmap/core/angles.hpp"
#include "blockmap/core/check.hpp"
#include "blockmap/planes/corner_look.hpp"
#include "blockmap/planes/polygon.hpp"

namespace blockmap::planes {
namespace {

ShapeOptions shape_options(const PlanesConfig& config) noexcept {
  ShapeOptions options;
  options.min_points = config.min_points_for_shape;
  options.max_planarity_ratio = config.max_planarity_ratio;
  options.max_line_ratio = config.max_line_ratio;
  options.coarse_second_look = config.coarse_second_look;
  options.max_noisy_slab_ratio = config.max_noisy_slab_ratio;
  options.noisy_slab_per_noise = config.noisy_slab_per_noise;
  options.level_slices = config.walls_from_lines;
  options.every_sample_votes = config.voting_mode == VotingMode::kEveryOrientation;
  return options;
}

// The orientation grid's bytes and searched rows. Its kernels hold only searched rows, so
// their size depends on the geometry (walls and roofs search a tenth of the sphere): one is
// sized in a scratch arena (its kernels counted, not filled), itself sized by the bound for
// any orientation, and measured. Start-up only (budgets are checked before anything runs).
struct MeasuredGrid {
  double bytes = 0.0;
  double rows = 0.0;
};
MeasuredGrid measured_orientation_grid(const PlanesConfig& config) {
  // The bound: cells over the half sphere plus one per band, each with a surface kernel (a
  // disc of normal_kernel_deg), a line kernel (a half circle) and neighbour entries.
  const double pi = std::numbers::pi;
  const double per_rad = 180.0 / pi / config.angle_bin_deg;
  const double cells = 2.0 * pi * per_rad * per_rad + 90.0 / config.angle_bin_deg + 2.0;
  const double kernel = pi * std::pow(config.normal_kernel_deg / config.angle_bin_deg + 1.5, 2.0) +
                        2.0 * 180.0 / config.angle_bin_deg + 8.0;
  const double bound =
      cells *
      (sizeof(Eigen::Vector3f) + 5 * sizeof(std::uint32_t) + kernel * sizeof(std::uint32_t) +
       OrientationGrid::kMaxNeighbours * sizeof(OrientationGrid::Neighbour) + 1);
  // Past this the bound itself is the answer: no budget takes it, and measuring would take it.
  constexpr double kMaxMeasuredBytes = 256.0 * 1024.0 * 1024.0;
  if (bound > kMaxMeasuredBytes) {
    return {bound, cells};
  }
  Arena scratch(static_cast<std::size_t>(bound) + (std::size_t{1} << 12));
  OrientationGrid grid;
  grid.init(scratch, config.angle_bin_deg, config.orientation_mode,
            config.orientation_tolerance_deg, config.normal_kernel_deg,
            OrientationGrid::Contents::kSizesOnly);
  return {static_cast<double>(scratch.used_bytes()), static_cast<double>(grid.row_count())};
}

// The inlier band: this many times the fit's RMS distance, grown in at most this many extra
// refinement steps.
constexpr double kBandPerRmse = 3.0;
constexpr std::uint32_t kMaxBandSteps = 6;

std::uint32_t whole_ratio(double a, double b) {
  return static_cast<std::uint32_t>(std::lround(a / b));
}

// Sections are kept (SectionCache) with kept shapes, when they are small enough.
bool keeps_sections(const PlanesConfig& config) noexcept {
  return config.keep_shapes &&
         SectionCache::supports(whole_ratio(config.section_size_m, config.section_stride_m()));
}

}  // namespace

void PlaneDetector::init(Arena& arena, const PlanesConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), "invalid planes configuration (validate() says why)");
  config_ = config;
  orientations_.init(arena, config.angle_bin_deg, config.orientation_mode,
                     config.orientation_tolerance_deg, config.normal_kernel_deg);
  voxels_.init(arena, config.sample_size_m, config.max_samples, block_capacity(config));
  if (config.keep_shapes) {
    voxels_.keep_shapes(arena);
  }
  sections_.init(arena, block_capacity(config),
                 whole_ratio(config.section_size_m, config.section_stride_m()),
                 config.section_stride_m());
  // d relative to the section centre reaches half the section's diagonal.
  const double half_range_m = 0.5 * std::sqrt(3.0) * config.section_size_m + config.d_bin_m;
  // Votes of a section: each sample votes for at most the kernel's rows, or all rows.
  accumulator_.init(arena, orientations_, half_range_m, config.d_bin_m,
                    config.max_samples_per_section * 32);
  merger_.init(arena, config);
  caching_ = keeps_sections(config);
  if (caching_) {
    cache_.init(arena, block_capacity(config), config.max_kept_sections, config.max_patches);
  }
  block_free_points_ =
      arena.allocate_array<std::uint32_t>(block_capacity(config), "planes.detector");
  section_samples_ =
      arena.allocate_array<std::uint32_t>(config.max_samples_per_section, "planes.detector");
  section_positions_ =
      arena.allocate_array<Eigen::Vector3f>(config.max_samples_per_section, "planes.detector");
  inliers_ = arena.allocate_array<std::uint32_t>(config.max_samples_per_section, "planes.detector");
  peaks_ = arena.allocate_array<HoughPeak>(config.max_planes_per_section, "planes.detector");
  cos_inlier_angle_ = static_cast<float>(std::cos(config.inlier_angle_deg * kRadiansPerDegree));
}

std::size_t PlaneDetector::arena_budget_bytes(const PlanesConfig& config) noexcept {
  const MeasuredGrid grid = measured_orientation_grid(config);
  const double half_range = 0.5 * std::sqrt(3.0) * config.section_size_m + config.d_bin_m;
  const double d_bins = 2.0 * std::ceil(half_range / config.d_bin_m);
  const auto voxels = static_cast<double>(
      VoxelGrid::arena_bytes(config.max_samples, block_capacity(config)) +
      (config.keep_shapes ? VoxelGrid::shape_cache_bytes(config.max_samples, block_capacity(config))
                          : 0));
  const auto sections = static_cast<double>(SectionGrid::arena_bytes(
      block_capacity(config), whole_ratio(config.section_size_m, config.section_stride_m())));
  const double accumulator =
      grid.rows * d_bins * sizeof(float) +
      static_cast<double>(config.max_samples_per_section) * 32 * sizeof(std::uint32_t);
  const auto merger = static_cast<double>(PlaneMerger::arena_bytes(config));
  const auto cache = static_cast<double>(keeps_sections(config)
                                             ? SectionCache::arena_bytes(block_capacity(config),
                                                                         config.max_kept_sections,
                                                                         config.max_patches)
                                             : 0);
  const double section = static_cast<double>(block_capacity(config)) * sizeof(std::uint32_t) +
                         static_cast<double>(config.max_samples_per_section) *
                             (2 * sizeof(std::uint32_t) + sizeof(Eigen::Vector3f)) +
                         static_cast<double>(config.max_planes_per_section) * sizeof(HoughPeak);
  // Alignment padding: a few dozen allocations of at most 64 bytes each.
  const double bytes =
      grid.bytes + voxels + sections + accumulator + merger + cache + section + 65536.0;
  // More than a quarter of the address space is said as that quarter: no budget takes it,
  // and the mapper's sum of its stages' bytes stays a number.
  constexpr std::size_t kMaxBytes = std::numeric_limits<std::size_t>::max() / 4;
  return bytes < static_cast<double>(kMaxBytes) ? static_cast<std::size_t>(bytes) : kMaxBytes;
}

void PlaneDetector::clear() noexcept {
  voxels_.clear();
  if (caching_) {
    cache_.invalidate();  // block indices start over
  }
  merger_.clear();
  stats_ = DetectionStats{};
}

void PlaneDetector::add_points(std::span<const Eigen::Vector3f> points_m) noexcept {
  voxels_.add_points(points_m);
}

std::span<const msg::PlanePatch> PlaneDetector::detect() noexcept {
  stats_ = DetectionStats{};
  const VoxelGrid::Counters& counters = voxels_.counters();
  stats_.points = counters.points_added;
  stats_.points_dropped = counters.points_dropped_full + counters.points_dropped_range +
                          counters.points_dropped_nonfinite;
  voxels_.compact();
  sections_.build(voxels_);
  // The shape pass also clears what the last detection left in the samples (owners, and
  // orientation cells, looked up again by the first section a sample votes in), and sums
  // each block's voting points: at first, all of them are free.
  voxels_.estimate_shapes(shape_options(config_), block_free_points_);
  stats_.surface_noise_m = voxels_.surface_noise_m();
  stats_.shapes_reused = voxels_.shapes_reused();
  stats_.planar_samples = voxels_.shape_tally().planar;
  stats_.linear_samples = voxels_.shape_tally().linear;
  stats_.scattered_samples = voxels_.shape_tally().scattered;
  stats_.samples = voxels_.size();
  merger_.clear();
  if (caching_) {
    cache_.begin(voxels_, exclusions_salt_);
  }
  for (std::size_t section = 0; section < sections_.sections().size(); ++section) {
    detect_in_section(section);
  }
  stats_.sections = sections_.sections().size();
  stats_.section_planes = merger_.section_plane_count();
  if (caching_) {
    cache_.end(merger_.section_planes(), merger_.counters().section_planes_dropped_full == 0);
  }
  std::span<const msg::PlanePatch> planes = merger_.merge();
  std::uint64_t steps_dropped = 0;
  // The corner look reads the merged walls; what it finds is merged with the rest. It is for
  // clouds blurred by pose errors (in a crisp one the votes find what it would), and not for
  // walls from a level laser's traces (no height to look along: walls_from_lines).
  if (config_.corner_look && !config_.walls_from_lines &&
      stats_.surface_noise_m >= config_.corner_look_min_noise_m) {
    const CornerLookCounters corners =
        CornerLook(config_).look(planes, stats_.surface_noise_m, voxels_, merger_);
    stats_.corners_looked_at = corners.corners_tried;
    stats_.corner_walls = corners.walls_found + corners.steps_found;
    steps_dropped = corners.steps_dropped;
    if (stats_.corner_walls > 0) {
      planes = merger_.merge();
    }
  }
  stats_.planes = planes.size();
  stats_.planes_excluded = merger_.counters().planes_excluded;
  stats_.overflows = sections_.counters().sections_dropped_full +
                     sections_.counters().voxels_dropped_full +
                     merger_.counters().section_planes_dropped_full +
                     merger_.counters().planes_dropped_full + steps_dropped;
  return planes;
}

bool PlaneDetector::votes(const Voxel& voxel) const noexcept {
  return config_.voting_mode == VotingMode::kEveryOrientation ||
         voxel.shape == LocalShape::kPlanar || voxel.shape == LocalShape::kLinear;
}

void PlaneDetector::vote_sample(const Voxel& voxel, const Eigen::Vector3f& position_m) noexcept {
  const auto weight = static_cast<float>(voxel.point_count);
  const auto vote = [&](std::uint32_t row) {
    accumulator_.vote(row, position_m, weight);
    ++stats_.votes;
  };
  if (config_.voting_mode == VotingMode::kEveryOrientation) {
    for (std::uint32_t row = 0; row < orientations_.row_count(); ++row) {
      vote(row);
    }
    return;
  }
  const auto vote_kernel = [&](std::span<const std::uint32_t> rows) {
    accumulator_.vote_rows(rows, position_m, weight);
    stats_.votes += rows.size();
  };
  switch (voxel.shape) {
    case LocalShape::kPlanar:
      vote_kernel(orientations_.surface_kernel(voxel.axis_cell));
      break;
    case LocalShape::kLinear:
      vote_kernel(orientations_.line_kernel(voxel.axis_cell));
      break;
    case LocalShape::kTooFewPoints:
    case LocalShape::kScattered:
      break;  // no surface here to vote for
  }
}

void PlaneDetector::set_exclusions(std::span<const PlaneExclusion> exclusions) noexcept {
  merger_.set_exclusions(exclusions);
  // refine() asks the exclusions only for walls from lines: then a section's planes depend on
  // them, and new exclusions make every kept section new.
  exclusions_salt_ = config_.walls_from_lines ? SectionCache::salt_of(exclusions) : 0;
}

void PlaneDetector::detect_in_section(std::size_t index) noexcept {
  // Samples that an earlier, overlapping section gave to a plane neither vote nor count: if
  // too few points are left for a plane, the section is done before its samples are read.
  const CellKey section = sections_.sections()[index];
  const std::span<const std::uint32_t> blocks = sections_.blocks_of(index);
  const SectionCache::Entry* before = caching_ ? cache_.previous(section) : nullptr;
  std::uint64_t free_points = 0;
  for (const std::uint32_t block : blocks) {
    free_points += block_free_points_[block];
  }
  if (static_cast<double>(free_points) < config_.min_votes) {
    if (before != nullptr && before->took_samples != 0) {
      cache_.forget_taken(section, blocks, voxels_);
    }
    if (before != nullptr && before->plane_count == 0 && before->took_samples == 0) {
      // A barren section that an earlier one has taken points from, for now, keeps its last
      // search: when it has them back it is as barren as it was (still_barren()).
      cache_.record(*before);
    }
    return;
  }
  ++stats_.sections_searched;
  if (!caching_) {
    search_section(section, blocks);
    return;
  }
  SectionCache::Entry entry{
      .section = section,
      .signature = cache_.signature(section, blocks),
      .first_plane = static_cast<std::uint32_t>(merger_.section_plane_count())};
  if (before != nullptr && before->signature == entry.signature) {
    replay_section(*before, section, blocks);
    entry.took_samples = before->took_samples;
    entry.searched_points = before->searched_points;
    ++stats_.sections_replayed;
  } else if (before != nullptr && still_barren(*before, free_points)) {
    // Nothing to replay: it gave no plane and took no sample.
    entry.searched_points = before->searched_points;
    ++stats_.sections_replayed;
    ++stats_.sections_still_barren;
  } else if (before != nullptr && settled(*before, free_points)) {
    entry.took_samples = replay_settled_section(*before, section, blocks) ? 1 : 0;
    entry.searched_points = before->searched_points;
    ++stats_.sections_replayed;
    ++stats_.sections_settled;
  } else {
    entry.searched_points = static_cast<std::uint16_t>(
        std::min<std::uint64_t>(free_points, SectionCache::kMaxSearchedPoints));
    // What this section took last time (if it was searched then) is decided again.
    cache_.forget_taken(section, blocks, voxels_);
    const std::uint64_t taken_before = stats_.samples_taken;
    search_section(section, blocks);
    entry.took_samples = stats_.samples_taken > taken_before ? 1 : 0;
  }
  entry.plane_count = static_cast<std::uint8_t>(merger_.section_plane_count() - entry.first_plane);
  cache_.record(entry);
}

bool PlaneDetector::still_barren(const SectionCache::Entry& before,
                                 std::uint64_t free_points) const noexcept {
  // A count that was capped says nothing about growth: searched again.
  return config_.barren_section_growth > 0.0 && before.plane_count == 0 &&
         before.took_samples == 0 && before.searched_points < SectionCache::kMaxSearchedPoints &&
         static_cast<double>(free_points) <
             static_cast<double>(before.searched_points) * (1.0 + config_.barren_section_growth);
}

bool PlaneDetector::settled(const SectionCache::Entry& before,
                            std::uint64_t free_points) const noexcept {
  // Shrunk: samples it took may have left the window, or an earlier section took them; its
  // planes may not hold any more.
  return config_.settled_section_growth > 0.0 && before.plane_count > 0 &&
         before.searched_points < SectionCache::kMaxSearchedPoints &&
         free_points >= before.searched_points &&
         static_cast<double>(free_points) <
             static_cast<double>(before.searched_points) * (1.0 + config_.settled_section_growth);
}

bool PlaneDetector::replay_settled_section(const SectionCache::Entry& before, CellKey section,
                                           std::span<const std::uint32_t> blocks) noexcept {
  for (const SectionPlane& plane : cache_.planes_of(before)) {
    merger_.add(plane);
  }
  if (before.took_samples == 0) {
    return false;
  }
  // What it took last time, per block, before its claims are forgotten (cells that left the
  // window among them) and made again for the samples that are there and free.
  constexpr std::size_t kEdge = SectionCache::kMaxBlocksPerSection;
  std::array<std::uint64_t, kEdge * kEdge * kEdge> taken{};
  BLOCKMAP_CHECK_MSG(blocks.size() <= taken.size(), "a kept section of more than 2 x 2 x 2 blocks");
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    taken[k] = cache_.taken_by(section, blocks[k], voxels_.block_key(blocks[k])) &
               voxels_.live_mask(blocks[k]);
  }
  cache_.forget_taken(section, blocks, voxels_);
  const auto owner = static_cast<std::int32_t>(merger_.section_plane_count());
  const std::span<Voxel> voxels = voxels_.voxels();
  bool took = false;
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const std::uint64_t live = voxels_.live_mask(blocks[k]);
    const std::uint32_t first = voxels_.block_range(blocks[k]).first;
    for (std::uint64_t cells = taken[k]; cells != 0; cells &= cells - 1) {
      const auto bit = static_cast<std::uint32_t>(std::countr_zero(cells));
      const std::uint64_t below = live & ((std::uint64_t{1} << bit) - 1);
      Voxel& voxel = voxels[first + static_cast<std::uint32_t>(std::popcount(below))];
      if (voxel.owner < 0) {
        take_sample(voxel, owner, section);
        took = true;
      }
    }
  }
  return took;
}

void PlaneDetector::search_section(CellKey section,
                                   std::span<const std::uint32_t> blocks) noexcept {
  const std::size_t count = sections_.gather(voxels_, blocks, section_samples_);
  const std::span<Voxel> voxels = voxels_.voxels();
  const Eigen::Vector3f centre = sections_.centre_m(section);
  accumulator_.clear();
  for (std::size_t i = 0; i < count; ++i) {
    Voxel& voxel = voxels[section_samples_[i]];
    section_positions_[i] = voxels_.centroid_m(voxel) - centre;
    if (voxel.owner < 0 && voxel.point_count > 0) {
      if (voxel.axis_cell == kAxisCellUnknown &&
          (voxel.shape == LocalShape::kPlanar || voxel.shape == LocalShape::kLinear)) {
        voxel.axis_cell = orientations_.cell_of(voxel.axis);
      }
      vote_sample(voxel, section_positions_[i]);
    }
  }
  const std::size_t peaks = accumulator_.find_peaks(static_cast<float>(config_.min_votes), peaks_);
  stats_.peaks += peaks;
  for (std::size_t i = 0; i < peaks; ++i) {
    SectionPlane plane;
    plane.section = section;
    if (refine(peaks_[i], centre, count, plane)) {
      merger_.add(plane);
    }
  }
}

void PlaneDetector::replay_section(const SectionCache::Entry& before, CellKey section,
                                   std::span<const std::uint32_t> blocks) noexcept {
  for (const SectionPlane& plane : cache_.planes_of(before)) {
    merger_.add(plane);
  }
  if (before.took_samples == 0) {
    return;
  }
  // The owner only has to say "taken": no later step asks which plane took a sample.
  const auto owner = static_cast<std::int32_t>(merger_.section_plane_count());
  const std::span<Voxel> voxels = voxels_.voxels();
  for (const std::uint32_t block : blocks) {
    const std::uint64_t live = voxels_.live_mask(block);
    const std::uint32_t first = voxels_.block_range(block).first;
    for (std::uint64_t cells = cache_.retake(section, block, voxels_.block_key(block)); cells != 0;
         cells &= cells - 1) {
      const auto bit = static_cast<std::uint32_t>(std::countr_zero(cells));
      const std::uint64_t below = live & ((std::uint64_t{1} << bit) - 1);
      claim_sample(voxels[first + static_cast<std::uint32_t>(std::popcount(below))], owner);
    }
  }
}

void PlaneDetector::claim_sample(Voxel& voxel, std::int32_t owner) noexcept {
  voxel.owner = owner;
  block_free_points_[voxel.block] -= votes(voxel) ? voxel.point_count : 0;
  ++stats_.samples_taken;
}

void PlaneDetector::take_sample(Voxel& voxel, std::int32_t owner, CellKey section) noexcept {
  claim_sample(voxel, owner);
  if (caching_) {
    const auto cell = unpack_cell(voxel.key);
    cache_.take(section, voxel.block, voxels_.block_key(voxel.block),
                bit_in_block(cell.x(), cell.y(), cell.z()));
  }
}

bool PlaneDetector::refine(const HoughPeak& peak, const Eigen::Vector3f& section_centre_m,
                           std::size_t sample_count, SectionPlane& out) noexcept {
  const std::span<Voxel> voxels = voxels_.voxels();
  const Eigen::Vector3d centre = section_centre_m.cast<double>();
  Eigen::Vector3d normal = peak.normal.cast<double>();
  auto d_m = static_cast<double>(peak.d_m);  // relative to the section centre
  PointMoments moments;
  std::size_t inliers = 0;
  // The inlier band follows the plane's own noise: a wall blurred by pose errors is a slab
  // wider than inlier_distance_m, and a band narrower than it leaves the slab's shoulders
  // to come back as parallel planes. Three times the RMS distance holds a slab's points; the
  // band grows from inlier_distance_m, at most to max_inlier_distance_m.
  double band_m = config_.inlier_distance_m;
  bool from_line = false;
  const std::uint32_t iterations = std::max<std::uint32_t>(config_.refine_iterations, 1);
  for (std::uint32_t iteration = 0; iteration < iterations + kMaxBandSteps; ++iteration) {
    // Once the band has grown, the plane is a noisy slab: its scattered samples are its points.
    const bool take_scattered = band_m > config_.inlier_distance_m;
    select_inliers(normal.cast<float>(), static_cast<float>(d_m), static_cast<float>(band_m),
                   take_scattered, centre, sample_count, moments, inliers);
    if (moments.weight < config_.min_votes) {
      return false;
    }
    const PlaneFit fit = merger_.fit_of(moments);
    // Points along one line fit every plane through it: not a plane. (With walls_from_lines a
    // horizontal line is its vertical wall, and eigenvalues_m2(1) its spread along the line: a
    // blob in the slice is not a wall either.)
    if (!fit.valid || std::sqrt(fit.eigenvalues_m2(1)) < 0.5 * config_.sample_size_m) {
      return false;
    }
    // A level laser's own scan plane holds all its returns: refused before it claims them.
    if (config_.walls_from_lines &&
        merger_.excluded(fit.normal_unit, fit.d_m + fit.normal_unit.dot(centre))) {
      return false;
    }
    from_line = fit.from_line;
    normal = fit.normal_unit;
    d_m = fit.d_m;
    const double next_band_m = std::clamp(kBandPerRmse * fit.rmse_m, config_.inlier_distance_m,
                                          config_.max_inlier_distance_m);
    const bool band_settled = next_band_m < band_m * 1.1;
    band_m = std::max(band_m, next_band_m);
    if (iteration + 1 >= iterations && band_settled) {
      break;
    }
  }
  if (!orientation_searched(normal)) {
    return false;
  }
  const auto owner = static_cast<std::int32_t>(merger_.section_plane_count());
  for (std::size_t k = 0; k < inliers; ++k) {
    take_sample(voxels[section_samples_[inliers_[k]]], owner, out.section);
  }
  out.moments = moments.shifted(centre);
  out.normal_unit = normal;
  out.d_m = d_m + normal.dot(centre);
  set_corners(normal, d_m, inliers, from_line, out);
  for (Eigen::Vector3f& corner : out.corners_m) {
    corner += section_centre_m;
  }
  return true;
}

void PlaneDetector::select_inliers(const Eigen::Vector3f& normal, float d_m, float band_m,
                                   bool take_scattered, const Eigen::Vector3d& centre_m,
                                   std::size_t sample_count, PointMoments& moments,
                                   std::size_t& inliers) noexcept {
  const std::span<const Voxel> voxels = voxels_.voxels();
  moments = PointMoments{};
  inliers = 0;
  for (std::size_t i = 0; i < sample_count; ++i) {
    const Voxel& voxel = voxels[section_samples_[i]];
    // Scattered samples (foliage, corners where two walls meet) would pull the fit round.
    if (voxel.owner >= 0 || voxel.point_count == 0 ||
        (voxel.shape == LocalShape::kScattered && !take_scattered) ||
        std::abs(normal.dot(section_positions_[i]) - d_m) > band_m ||
        (voxel.shape == LocalShape::kPlanar &&
         std::abs(voxel.axis.dot(normal)) < cos_inlier_angle_)) {
      continue;
    }
    moments.merge(voxels_.moments(voxel, centre_m));
    inliers_[inliers++] = static_cast<std::uint32_t>(i);
  }
}

bool PlaneDetector::orientation_searched(const Eigen::Vector3d& normal) const noexcept {
  if (config_.orientation_mode == OrientationMode::kAny) {
    return true;
  }
  const double tolerance = config_.orientation_tolerance_deg * kRadiansPerDegree;
  const double z = std::abs(normal.z());
  return z >= std::cos(tolerance) || z <= std::sin(tolerance);
}

void PlaneDetector::set_corners(const Eigen::Vector3d& normal, double d_m, std::size_t inlier_count,
                                bool from_line, SectionPlane& out) const noexcept {
  // The rectangle, in the plane's own axes, of its samples' centroids (section-relative).
  const auto [u, v] = plane_basis(normal);
  double u_min = std::numeric_limits<double>::infinity();
  double u_max = -u_min;
  double v_min = u_min;
  double v_max = -u_min;
  for (std::size_t k = 0; k < inlier_count; ++k) {
    const Eigen::Vector3d p = section_positions_[inliers_[k]].cast<double>();
    u_min = std::min(u_min, u.dot(p));
    u_max = std::max(u_max, u.dot(p));
    v_min = std::min(v_min, v.dot(p));
    v_max = std::max(v_max, v.dot(p));
  }
  if (from_line) {
    // A line's samples stand for the points of their voxels: the wall is a voxel high at least.
    const double half_m = 0.5 * config_.sample_size_m;
    const auto widen = [half_m](double& low, double& high) {
      const double middle = 0.5 * (low + high);
      low = std::min(low, middle - half_m);
      high = std::max(high, middle + half_m);
    };
    widen(u_min, u_max);
    widen(v_min, v_max);
  }
  const Eigen::Vector3d foot = normal * d_m;
  out.corners_m = {
      (foot + u_min * u + v_min * v).cast<float>(), (foot + u_max * u + v_min * v).cast<float>(),
      (foot + u_max * u + v_max * v).cast<float>(), (foot + u_min * u + v_max * v).cast<float>()};
}

std::size_t PlaneDetector::memory_bytes() const noexcept {
  return orientations_.memory_bytes() + voxels_.memory_bytes() + sections_.memory_bytes() +
         accumulator_.memory_bytes() + merger_.memory_bytes() +
         (caching_ ? cache_.memory_bytes() : 0) + block_free_points_.size_bytes() +
         section_samples_.size_bytes() + section_positions_.size_bytes() + inliers_.size_bytes() +
         peaks_.size_bytes();
}

}  // namespace blockmap::planes
