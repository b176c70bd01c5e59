#include "blockmap/planes/corner_look.hpp"
#include "blockmap/core/angles.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Eigenvalues>

namespace blockmap::planes {
namespace {

// Where to look. The first band around the square plane is wide: in a blurred cloud a wall's
// end, as its polygon says, is a few tenths of a metre off. Points from kBehindM behind the
// corner count (the old wall's end may lie inside the new wall's slab), and from
// kCornerAboveFootM above the old wall's foot (not the ground).
constexpr double kSearchBandM = 0.8;
constexpr double kBehindM = 0.5;
constexpr double kCornerAboveFootM = 0.3;
constexpr double kAboveTopM = 1.0;
// The fit: kFitSteps rounds of fitting and taking the points within kBandPerRmse RMS distances
// of the fit (as refine() does), the band between the detector's inlier distances.
constexpr std::uint32_t kFitSteps = 4;
constexpr double kBandPerRmse = 3.0;
// What makes it a wall: at most kMaxTurnDeg off square to the old wall, vertical within the
// searched orientations, at least kMinPoints points that start within kMaxStartM of the
// corner and run on, without a gap longer than kMaxGapM, for at least kMinLengthM; and as
// flat as the old wall's noise (or the cloud's) allows, within kMaxRmsPerNoise times it. A
// hedge in front of a building's side is a slab several times thicker than the walls of a
// crisp cloud.
constexpr double kMaxTurnDeg = 10.0;
constexpr double kMinPoints = 100.0;
constexpr double kMaxStartM = 1.5;
constexpr double kMaxGapM = 1.0;
constexpr double kMinLengthM = kMinCornerReachM;
constexpr double kMaxRmsPerNoise = 3.0;
// The planes found already: their samples within this many RMS distances (plus
// merge_distance_m), inside their box grown by kBoxMarginM, are theirs (as the merger's slab).
constexpr double kSlabPerRmse = 3.0;
constexpr double kBoxMarginM = 0.5;
// Which side of a wall is inside: the returns kInFrontFromM to kInFrontToM in front of it
// (beyond the tails of a blurred wall's own returns), from kBelowFootM under its foot to half
// its height, kShortOfEndsM short of its ends (where the building's side walls stand). The
// inside has at most kInsideShare of the other side's returns, and the other side at least
// kMinStreetReturns.
constexpr double kInFrontFromM = 1.5;
constexpr double kInFrontToM = 5.0;
constexpr double kBelowFootM = 1.0;
constexpr double kShortOfEndsM = 1.5;
constexpr double kInsideShare = 0.25;
constexpr double kMinStreetReturns = 10.0;
// A step back (a notch): at least kMinStepM into the building (clear of the wall's own blurred
// returns, as the street in front of it is for way_inside()), and only at a wall's end with no
// side found within kStepClearM of it. The depths tried are the metres that hold the most
// points within kStepPeakBins bins either side and kStepPeakOverMean times the mean metre's
// (a blurred cloud's fog lies between the surfaces). The step's wall may begin up to
// kStepMaxStartM beyond the end (the end of a blurred wall lies up to a metre or two short of
// its corner, and from a street at a slant the first wall hides the notch's inner corner),
// and a bin with less than kStepRunMinShare of the run's mean points is a gap (the ground's
// fog, a few points a metre, would carry it on past the notch).
constexpr double kMinStepM = kInFrontFromM;
constexpr double kStepClearM = 3.0;
constexpr double kStepMaxStartM = kMaxStartM + kStepClearM;
constexpr double kStepRunMinShare = 0.1;
constexpr std::size_t kStepPeakBins = 4;
constexpr double kStepPeakOverMean = 3.0;
// The owner of the samples the look takes: taken, by no section's plane.
constexpr std::int32_t kTaken = std::numeric_limits<std::int32_t>::max();

}  // namespace

// One function, longer than most: the region's bounds, the walk over its blocks and the test
// of each sample share the corner's frame.
CornerLook::Gathered CornerLook::gather(const Corner& corner, const Eigen::Vector3d& normal,
                                        double offset_m, double band_m, double reach_to_m,
                                        std::span<const NearPlane> near, std::int32_t take_as,
                                        std::span<float, kBins> points_per_bin) noexcept {
  Gathered out;
  out.reach_min_m = std::numeric_limits<double>::infinity();
  out.reach_max_m = -out.reach_min_m;
  out.z_min_m = out.reach_min_m;
  out.z_max_m = -out.reach_min_m;
  std::fill(points_per_bin.begin(), points_per_bin.end(), 0.0f);
  const double block_m = voxels_->voxel_size_m() * static_cast<double>(kBlockEdge);
  // The region, in the corner's axes: along its way from kBehindM back, across within the
  // band of a plane that is at most kMaxTurnDeg off square.
  const double across_half_m =
      std::abs(offset_m) + band_m + std::sin(kMaxTurnDeg * kRadiansPerDegree) * reach_to_m;
  const Eigen::Vector3d& c = corner.corner_m;
  Eigen::Vector2d low(std::numeric_limits<double>::infinity(),
                      std::numeric_limits<double>::infinity());
  Eigen::Vector2d high = -low;
  for (const double t : {corner.reach_from_m, reach_to_m}) {
    for (const double s : {-across_half_m, across_half_m}) {
      const Eigen::Vector3d p = c + t * corner.along + s * corner.across;
      low = low.cwiseMin(p.head<2>());
      high = high.cwiseMax(p.head<2>());
    }
  }
  const auto block_of = [block_m](double x) {
    return static_cast<std::int64_t>(std::floor(x / block_m));
  };
  const std::int64_t z_low = block_of(corner.z_min_m);
  const std::int64_t z_high = block_of(corner.z_max_m);
  const std::span<Voxel> samples = voxels_->voxels();
  const double reach_mid_m = 0.5 * (reach_to_m + corner.reach_from_m);
  const double reach_half_m = 0.5 * (reach_to_m - corner.reach_from_m);
  for (std::int64_t bx = block_of(low.x()); bx <= block_of(high.x()); ++bx) {
    for (std::int64_t by = block_of(low.y()); by <= block_of(high.y()); ++by) {
      // A column whose centre is more than half a block's diagonal out of the region.
      const Eigen::Vector3d column((static_cast<double>(bx) + 0.5) * block_m,
                                   (static_cast<double>(by) + 0.5) * block_m, c.z());
      const double t = corner.along.dot(column - c) - reach_mid_m;
      const double s = corner.across.dot(column - c);
      const double margin_m = 0.75 * block_m;
      if (std::abs(t) > reach_half_m + margin_m || std::abs(s) > across_half_m + margin_m) {
        continue;
      }
      for (std::int64_t bz = z_low; bz <= z_high; ++bz) {
        const std::uint32_t block = voxels_->find_block(pack_cell(bx, by, bz));
        if (block == CellIndex::kAbsent) {
          continue;
        }
        const VoxelGrid::BlockRange range = voxels_->block_range(block);
        for (Voxel& voxel : samples.subspan(range.first, range.count)) {
          if ((corner.free_only && voxel.owner >= 0) || voxel.point_count == 0) {
            continue;
          }
          const Eigen::Vector3d p = voxels_->centroid_m(voxel).cast<double>() - c;
          const double reach = corner.along.dot(p);
          const double z = p.z() + c.z();
          if (reach < corner.reach_from_m || reach > reach_to_m || z < corner.z_min_m ||
              z > corner.z_max_m || std::abs(normal.dot(p) - offset_m) > band_m) {
            continue;
          }
          const Eigen::Vector3d q = p + c;
          const auto owned = [&q](const NearPlane& plane) {
            return std::abs(plane.normal.dot(q) - plane.d_m) <= plane.slab_m &&
                   (q.array() >= plane.box_min_m.array()).all() &&
                   (q.array() <= plane.box_max_m.array()).all();
          };
          if (std::any_of(near.begin(), near.end(), owned)) {
            continue;
          }
          out.moments.merge(voxels_->moments(voxel, c));
          const auto bin = std::min<std::size_t>(
              static_cast<std::size_t>((reach + kBehindM) / kBinM), kBins - 1);
          points_per_bin[bin] += static_cast<float>(voxel.point_count);
          out.reach_min_m = std::min(out.reach_min_m, reach);
          out.reach_max_m = std::max(out.reach_max_m, reach);
          out.z_min_m = std::min(out.z_min_m, z);
          out.z_max_m = std::max(out.z_max_m, z);
          if (take_as >= 0) {
            voxel.owner = take_as;
          }
        }
      }
    }
  }
  return out;
}

namespace {

// Where the run of points that begins within max_start_m of the corner ends (along its way),
// or a negative value when no run begins there. Bin k covers [k * kBinM - kBehindM, ...). A
// bin with fewer than min_share of the run's mean points per bin so far is a gap.
template <std::size_t N>
double run_end_m(std::span<const float, N> points_per_bin, double bin_m, double behind_m,
                 double max_start_m, double min_share) {
  const auto start_of = [&](std::size_t bin) {
    return static_cast<double>(bin) * bin_m - behind_m;
  };
  std::size_t first = N;
  for (std::size_t bin = 0; bin < N && start_of(bin) <= max_start_m; ++bin) {
    if (points_per_bin[bin] > 0.0f) {
      first = bin;
      break;
    }
  }
  if (first == N) {
    return -1.0;
  }
  std::size_t last = first;
  auto run_points = static_cast<double>(points_per_bin[first]);
  for (std::size_t bin = first + 1; bin < N; ++bin) {
    const auto points = static_cast<double>(points_per_bin[bin]);
    const double mean_points = run_points / static_cast<double>(last + 1 - first);
    if (points > 0.0 && points >= min_share * mean_points) {
      if (start_of(bin) - start_of(last + 1) > kMaxGapM) {
        break;
      }
      last = bin;
      run_points += points;
    }
  }
  return start_of(last + 1);
}

}  // namespace

CornerLook::CornerFit CornerLook::fit_corner(const Corner& corner, double noise_rmse_m,
                                             std::span<const NearPlane> near) noexcept {
  static_assert(kBinM * static_cast<double>(kBins) - kBehindM == kMaxCornerReachM);
  std::array<float, kBins> bins{};
  CornerFit out;
  out.normal = corner.across;
  out.band_m = kSearchBandM;
  out.reach_to_m = std::min(corner.reach_m, kMaxCornerReachM);
  for (std::uint32_t step = 0; step <= kFitSteps; ++step) {
    out.gathered =
        gather(corner, out.normal, out.offset_m, out.band_m, out.reach_to_m, near, -1, bins);
    if (out.gathered.moments.weight < kMinPoints) {
      return out;
    }
    // Square to the old wall: buildings have square corners (the paper's models); a wall
    // glimpsed through pose errors is a fan of a few scans, whose own turn is noise. Its lean
    // stays free: a fan that leans further than a wall may is not one.
    out.fit = fit_plane_along_axis(out.gathered.moments, corner.wall_normal);
    if (!out.fit.valid || std::abs(out.fit.normal_unit.dot(corner.across)) <
                              std::cos(kMaxTurnDeg * kRadiansPerDegree)) {
      return out;
    }
    if (step == kFitSteps) {
      break;  // the points of the last band, fitted: the answer
    }
    const double sign = out.fit.normal_unit.dot(corner.across) < 0.0 ? -1.0 : 1.0;
    out.normal = sign * out.fit.normal_unit;
    out.offset_m = sign * out.fit.d_m;
    out.band_m = std::clamp(kBandPerRmse * out.fit.rmse_m, config_.inlier_distance_m,
                            config_.max_inlier_distance_m);
    const double end_m =
        run_end_m<kBins>(bins, kBinM, kBehindM, corner.max_start_m, corner.run_min_share);
    if (end_m < 0.0) {
      return out;
    }
    out.reach_to_m = std::min(out.reach_to_m, end_m);
  }
  const double length_m = out.gathered.reach_max_m - std::max(out.gathered.reach_min_m, 0.0);
  out.upright = std::abs(out.fit.normal_unit.z()) <=
                std::sin(config_.orientation_tolerance_deg * kRadiansPerDegree);
  out.wall_like = length_m >= kMinLengthM && out.fit.rmse_m <= kMaxRmsPerNoise * noise_rmse_m;
  return out;
}

bool CornerLook::try_corner(const Corner& corner, double noise_rmse_m,
                            std::span<const NearPlane> near, SectionPlane& found_plane) noexcept {
  CornerFit found = fit_corner(corner, noise_rmse_m, near);
  Corner looked = corner;
  if (found.wall_like) {
    // What stands in front of a building's side (a hedge, a parked car) stands on the ground:
    // a fit of both leans, or lies off the side where the side is clear of it. So the upper
    // half is fitted too, and where the two disagree (the whole fit leans too far, or passes
    // the upper half's points further off than their own RMS distance), the upper half is
    // the side.
    Corner upper = corner;
    upper.z_min_m = 0.5 * (corner.z_min_m + corner.wall_top_m);
    const CornerFit top = fit_corner(upper, noise_rmse_m, near);
    const double apart_m =
        top.gathered.moments.weight >= kMinPoints
            ? std::abs(found.fit.normal_unit.dot(top.fit.centroid_m) - found.fit.d_m)
            : 0.0;
    if (!found.upright || apart_m > top.fit.rmse_m) {
      found = top;
      looked = upper;
    }
  }
  if (!found.wall_like || !found.upright) {
    return false;
  }
  const PlaneFit& fit = found.fit;
  std::array<float, kBins> bins{};
  const Gathered gathered = gather(looked, found.normal, found.offset_m, found.band_m,
                                   found.reach_to_m, near, kTaken, bins);
  SectionPlane plane;
  plane.section = corner.section;
  plane.moments = gathered.moments.shifted(corner.corner_m);
  plane.normal_unit = fit.normal_unit;
  plane.d_m = fit.d_m + fit.normal_unit.dot(corner.corner_m);
  // The rectangle of its samples, on the plane: along the corner's way, and up.
  const Eigen::Vector3d foot = corner.corner_m + fit.d_m * fit.normal_unit;
  const Eigen::Vector3d way =
      (corner.along - corner.along.dot(fit.normal_unit) * fit.normal_unit).normalized();
  const auto at = [&](double reach, double z) -> Eigen::Vector3f {
    Eigen::Vector3d p = foot + reach * way;
    p.z() = z;
    return p.cast<float>();
  };
  plane.corners_m = {
      at(gathered.reach_min_m, gathered.z_min_m), at(gathered.reach_max_m, gathered.z_min_m),
      at(gathered.reach_max_m, gathered.z_max_m), at(gathered.reach_min_m, gathered.z_max_m)};
  found_plane = plane;
  return true;
}

namespace {

// The extent of a plane's polygon along a direction.
CornerLook::Extent extent_along(const msg::PlanePatch& plane, const Eigen::Vector3d& direction) {
  CornerLook::Extent out;
  for (std::size_t i = 0; i < plane.polygon_size; ++i) {
    const double x = direction.dot(plane.polygon_m[i]);
    out.low = std::min(out.low, x);
    out.high = std::max(out.high, x);
  }
  return out;
}

}  // namespace

bool CornerLook::open_corner(std::span<const msg::PlanePatch> planes,
                             Corner& corner) const noexcept {
  const double cos_parallel = std::cos(kMaxTurnDeg * kRadiansPerDegree);
  const double corner_along = corner.along.dot(corner.corner_m);
  const double corner_across = corner.across.dot(corner.corner_m);
  for (const msg::PlanePatch& plane : planes) {
    if (plane.kind != msg::PlaneKind::kWall || plane.polygon_size == 0) {
      continue;
    }
    const double distance_m = std::abs(plane.normal.dot(corner.corner_m) - plane.d_m);
    const CornerLook::Extent reach = extent_along(plane, corner.along);
    // A wall already found there: the corner is closed.
    if (std::abs(plane.normal.dot(corner.across)) >= cos_parallel && distance_m <= kSearchBandM &&
        reach.high > corner_along + kMaxStartM &&
        reach.low < corner_along + std::max(kMinLengthM, corner.max_start_m)) {
      return false;
    }
    // A wall parallel to the old one, facing the corner on its way: the building's far side,
    // where the new wall ends.
    if (std::abs(plane.normal.dot(corner.along)) >= cos_parallel) {
      const CornerLook::Extent across = extent_along(plane, corner.across);
      const double ahead_m = corner.along.dot(plane.centroid_m) - corner_along;
      if (ahead_m > kMinLengthM && ahead_m < corner.reach_m &&
          across.low < corner_across + kMaxStartM && across.high > corner_across - kMaxStartM) {
        corner.reach_m = ahead_m + kMaxStartM;
      }
    }
  }
  return true;
}

bool CornerLook::side_near(std::span<const msg::PlanePatch> planes, const Corner& corner) noexcept {
  const double cos_parallel = std::cos(kMaxTurnDeg * kRadiansPerDegree);
  const double corner_along = corner.along.dot(corner.corner_m);
  return std::any_of(planes.begin(), planes.end(), [&](const msg::PlanePatch& plane) {
    if (plane.kind != msg::PlaneKind::kWall || plane.polygon_size == 0 ||
        std::abs(plane.normal.dot(corner.across)) < cos_parallel ||
        std::abs(plane.normal.dot(corner.corner_m) - plane.d_m) > kStepClearM) {
      return false;
    }
    const CornerLook::Extent reach = extent_along(plane, corner.along);
    return reach.high > corner_along - kMaxStartM && reach.low < corner_along + kStepClearM;
  });
}

std::size_t CornerLook::near_planes(std::span<const msg::PlanePatch> planes, const Corner& corner,
                                    double across_m,
                                    std::span<NearPlane, kMaxNearPlanes> near) const noexcept {
  // The region's box, generously: along its way, across it, its heights.
  const Eigen::Vector3d& c = corner.corner_m;
  Eigen::Vector3d low = c.cwiseMin(c + corner.reach_m * corner.along);
  Eigen::Vector3d high = c.cwiseMax(c + corner.reach_m * corner.along);
  low -= Eigen::Vector3d::Constant(across_m);
  high += Eigen::Vector3d::Constant(across_m);
  low.z() = corner.z_min_m;
  high.z() = corner.z_max_m;
  std::size_t count = 0;
  for (const msg::PlanePatch& plane : planes) {
    if (plane.polygon_size == 0 || count == near.size()) {
      continue;
    }
    NearPlane p;
    p.normal = plane.normal;
    p.d_m = plane.d_m;
    p.slab_m = kSlabPerRmse * plane.rmse_m + config_.merge_distance_m;
    p.box_min_m = plane.polygon_m[0];
    p.box_max_m = plane.polygon_m[0];
    for (std::size_t i = 1; i < plane.polygon_size; ++i) {
      p.box_min_m = p.box_min_m.cwiseMin(plane.polygon_m[i]);
      p.box_max_m = p.box_max_m.cwiseMax(plane.polygon_m[i]);
    }
    p.box_min_m -= Eigen::Vector3d::Constant(p.slab_m + kBoxMarginM);
    p.box_max_m += Eigen::Vector3d::Constant(p.slab_m + kBoxMarginM);
    if ((p.box_max_m.array() < low.array()).any() || (p.box_min_m.array() > high.array()).any()) {
      continue;
    }
    near[count++] = p;
  }
  return count;
}

int CornerLook::way_inside(const msg::PlanePatch& wall, const Eigen::Vector3d& out,
                           const Eigen::Vector3d& side, const Extent& ends,
                           const Extent& heights) noexcept {
  const double s_min = ends.low;
  const double s_max = ends.high;
  const double z_min = heights.low;
  const double z_max = heights.high;
  const Eigen::Vector3d base(wall.centroid_m.x(), wall.centroid_m.y(), z_min + kCornerAboveFootM);
  const double slab_m = kSlabPerRmse * wall.rmse_m + config_.merge_distance_m;
  const double middle_s = 0.5 * (s_min + s_max);
  std::array<double, 2> returns{};
  std::array<float, kBins> bins{};
  for (std::size_t k = 0; k < 2; ++k) {
    Corner front;
    front.corner_m = base + (middle_s - side.dot(base)) * side;
    front.across = side;
    front.along = k == 0 ? out : Eigen::Vector3d(-out);
    // From below the wall's foot (the street's ground counts; nothing is seen under a
    // building's floor) to half its height (a roof over the inside is seen from the street).
    front.z_min_m = z_min - kBelowFootM;
    front.z_max_m = 0.5 * (z_min + z_max);
    front.free_only = false;
    front.reach_from_m = std::max(slab_m, kInFrontFromM);
    // Short of the wall's ends: the building's side walls stand there.
    const double half_m = 0.5 * (s_max - s_min);
    const double band_m = std::max(half_m - kShortOfEndsM, 0.5 * half_m);
    returns[k] = gather(front, side, 0.0, band_m, kInFrontToM, {}, -1, bins).moments.weight;
  }
  if (std::max(returns[0], returns[1]) < kMinStreetReturns) {
    return 0;
  }
  if (returns[0] < kInsideShare * returns[1]) {
    return 1;
  }
  if (returns[1] < kInsideShare * returns[0]) {
    return -1;
  }
  return 0;
}

namespace {

// How far either side of a corner's way its square plane's points may lie: the widest band
// and the most a wall may turn over the reach, with a metre to spare.
double square_look_width_m(double reach_m) {
  return kSearchBandM + std::sin(kMaxTurnDeg * kRadiansPerDegree) * reach_m + 1.0;
}

}  // namespace

std::size_t CornerLook::step_depths(std::span<const msg::PlanePatch> planes, const Corner& corner,
                                    std::span<double, kMaxStepDepths> depths_m) noexcept {
  // Beyond the wall's end (from kBehindM back, along corner.across) and into the building
  // (from kMinStepM, along corner.along), counted by depth.
  const double reach_m = std::min(corner.reach_m, kMaxCornerReachM);
  std::array<NearPlane, kMaxNearPlanes> near;
  const std::size_t near_count = near_planes(planes, corner, reach_m + kBehindM, near);
  Corner beyond = corner;
  beyond.reach_from_m = kMinStepM;
  const double half_width_m = 0.5 * (reach_m + kBehindM);
  std::array<float, kBins> points_by_depth{};
  static_cast<void>(gather(beyond, corner.across, half_width_m - kBehindM, half_width_m, reach_m,
                           std::span(near).first(near_count), -1, points_by_depth));
  // The peaks (two bins, a metre) with at least kMinPoints, nearest first: the nearest surface
  // behind the end hides what lies further in (an L seen from its long side shows its notch
  // before its far side).
  const auto points_at = [&points_by_depth](std::size_t bin) {
    return static_cast<double>(points_by_depth[bin] + points_by_depth[bin + 1]);
  };
  const double searched_bins = (reach_m - kMinStepM) / kBinM;
  double all_points = 0.0;
  for (const float points : points_by_depth) {
    all_points += static_cast<double>(points);
  }
  const double least = std::max(kMinPoints, kStepPeakOverMean * 2.0 * all_points / searched_bins);
  std::size_t count = 0;
  for (std::size_t bin = 0; bin + 1 < kBins && count < depths_m.size(); ++bin) {
    const double points = points_at(bin);
    const std::size_t from = bin - std::min(bin, kStepPeakBins);
    const std::size_t to = std::min(bin + kStepPeakBins, kBins - 2);
    bool peak = points >= least;
    for (std::size_t other = from; peak && other <= to; ++other) {
      // Ties go to the nearer metre.
      peak = other < bin ? points > points_at(other) : points >= points_at(other);
    }
    if (peak) {
      depths_m[count++] = static_cast<double>(bin + 1) * kBinM - kBehindM;  // between the bins
    }
  }
  return count;
}

bool CornerLook::try_step(std::span<const msg::PlanePatch> planes, const Corner& corner,
                          double noise_rmse_m, SectionPlane& found_plane) noexcept {
  if (side_near(planes, corner)) {
    return false;
  }
  std::array<double, kMaxStepDepths> depths_m{};
  const std::size_t depth_count = step_depths(planes, corner, depths_m);
  for (const double depth_m : std::span(depths_m).first(depth_count)) {
    // The step's wall faces the way the old one does and runs on beyond its end, from the
    // corner of the notch: the corner look's fit from there.
    Corner step = corner;
    step.corner_m = corner.corner_m + depth_m * corner.along;
    step.across = -corner.along;
    step.along = corner.across;
    step.wall_normal = corner.across;
    step.reach_m = config_.corner_reach_m;
    step.max_start_m = kStepMaxStartM;
    step.run_min_share = kStepRunMinShare;
    step.section = kStepSection;
    if (!open_corner(planes, step)) {
      continue;
    }
    std::array<NearPlane, kMaxNearPlanes> near;
    const std::size_t near_count =
        near_planes(planes, step, square_look_width_m(step.reach_m), near);
    if (try_corner(step, noise_rmse_m, std::span(near).first(near_count), found_plane)) {
      return true;
    }
  }
  return false;
}

// One function, longer than most: each wall's two ends looked past in turn, in the wall's own
// frame, with the steps found handed to the merger at the end.
CornerLookCounters CornerLook::look(std::span<const msg::PlanePatch> planes, double surface_noise_m,
                                    VoxelGrid& voxels, PlaneMerger& merger) noexcept {
  voxels_ = &voxels;
  CornerLookCounters counters;
  // Steps come to the merger after the sides: their section key is after the sides' key.
  std::array<SectionPlane, kMaxSteps> steps;
  std::size_t step_count = 0;
  for (const msg::PlanePatch& wall : planes) {
    if (wall.kind != msg::PlaneKind::kWall || wall.polygon_size == 0) {
      continue;
    }
    // The wall seen from above: its horizontal normal, its direction, its ends and heights.
    const Eigen::Vector2d flat = wall.normal.head<2>().normalized();
    const Eigen::Vector3d out(flat.x(), flat.y(), 0.0);
    const Eigen::Vector3d side(-out.y(), out.x(), 0.0);
    const Extent ends = extent_along(wall, side);
    const Extent heights = extent_along(wall, Eigen::Vector3d::UnitZ());
    const Eigen::Vector3d base(wall.centroid_m.x(), wall.centroid_m.y(), 0.0);
    const auto corner_at = [&](double end_s, double way) {
      Corner corner;
      corner.corner_m = base + (end_s - side.dot(base)) * side;
      corner.corner_m.z() = heights.low + kCornerAboveFootM;
      corner.across = end_s == ends.low ? Eigen::Vector3d(-side) : side;
      corner.along = way * out;
      corner.wall_normal = wall.normal;
      corner.z_min_m = heights.low + kCornerAboveFootM;
      corner.z_max_m = heights.high + kAboveTopM;
      corner.wall_top_m = heights.high;
      corner.reach_m = config_.corner_reach_m;
      return corner;
    };
    // Both sides of the building found already (the usual case in a crisp cloud): no corner
    // to look at, and no need to tell the inside from the street.
    const auto both_closed = [&](double way) {
      Corner low = corner_at(ends.low, way);
      Corner high = corner_at(ends.high, way);
      return !open_corner(planes, low) && !open_corner(planes, high);
    };
    if (both_closed(1.0) || both_closed(-1.0)) {
      continue;
    }
    const int inside = way_inside(wall, out, side, ends, heights);
    if (inside == 0) {
      continue;  // no telling the building from the street: no corner to look at
    }
    const double noise_m = std::max(wall.rmse_m, surface_noise_m);
    for (const double end_s : {ends.low, ends.high}) {
      Corner corner = corner_at(end_s, static_cast<double>(inside));
      if (!open_corner(planes, corner)) {
        continue;
      }
      std::array<NearPlane, kMaxNearPlanes> near;
      const std::size_t near_count =
          near_planes(planes, corner, square_look_width_m(corner.reach_m), near);
      ++counters.corners_tried;
      SectionPlane found;
      if (try_corner(corner, noise_m, std::span(near).first(near_count), found)) {
        counters.walls_found += merger.add(found) ? 1u : 0u;
      } else if (try_step(planes, corner, noise_m, found)) {
        if (step_count < steps.size()) {
          steps[step_count++] = found;
        } else {
          ++counters.steps_dropped;
        }
      }
    }
  }
  for (const SectionPlane& step : std::span(steps).first(step_count)) {
    counters.steps_found += merger.add(step) ? 1u : 0u;
  }
  return counters;
}

}  // namespace blockmap::planes
