// A second look for the walls the Hough votes miss: the short sides of buildings that a robot
// driving along a street only glimpses. Their returns come from a few scans at a grazing
// angle, and pose errors of a few tenths of a degree turn them into a slab 0.3 m thick that
// no neighbourhood calls flat. Yet where a wall that was found ends, a building usually turns
// a corner. The look tries the plane through each end of each wall, square to it, into the
// building (the side of the wall a laser saw nothing behind): it fits the free samples near
// that plane by least squares, and keeps the fit only when its points say so (enough of
// them, standing upright, flat within the wall's own noise, in one piece from the corner;
// above a hedge that stands in front of it when the two disagree). Where no side is found, the
// building may step back instead (an L's or a T's notch, whose side faces away from the
// street): the look then tries a wall parallel to the first, set back into the building, that
// begins where the first one ends. The hypothesis only says where to look; the plane is where
// its points are.
#pragma once

#include <cstdint>
#include <limits>
#include <span>

#include <Eigen/Core>

#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/plane_merger.hpp"
#include "blockmap/planes/planes_config.hpp"
#include "blockmap/planes/point_moments.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::planes {

struct CornerLookCounters {
  std::uint64_t corners_tried = 0;  // wall ends with no wall found there
  std::uint64_t walls_found = 0;    // sides square to the wall, at its end
  std::uint64_t steps_found = 0;    // walls parallel to it, set back, beyond its end
  std::uint64_t steps_dropped = 0;  // more than CornerLook::kMaxSteps of them
};

class CornerLook {
 public:
  static constexpr std::size_t kMaxSteps = 16;  // steps found in one look

  explicit CornerLook(const PlanesConfig& config) noexcept : config_(config) {}

  // Looks at the corners of the walls among `planes` (the merged planes; the surface noise is
  // the detector's) and adds a section plane to `merger` for each wall found there; the
  // samples it took are marked taken. Allocates nothing.
  CornerLookCounters look(std::span<const msg::PlanePatch> planes, double surface_noise_m,
                          VoxelGrid& voxels, PlaneMerger& merger) noexcept;

  // An interval along some direction (empty: low > high).
  struct Extent {
    double low = std::numeric_limits<double>::infinity();
    double high = -std::numeric_limits<double>::infinity();
  };

 private:
  // Where to look: the corner (a wall's end, at its foot), the new wall's normal (horizontal,
  // along the old wall) and the way it would run (away from the old wall), its height range.
  struct Corner {
    Eigen::Vector3d corner_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d across = Eigen::Vector3d::UnitX();
    Eigen::Vector3d along = Eigen::Vector3d::UnitY();
    Eigen::Vector3d wall_normal = Eigen::Vector3d::UnitY();  // the old wall's: square to it
    double z_min_m = 0.0;
    double z_max_m = 0.0;
    double wall_top_m = 0.0;         // the old wall's
    double reach_m = 0.0;            // how far along its way it may run
    double reach_from_m = -0.5;      // and from where (behind the corner: a blurred end)
    double max_start_m = 1.5;        // its points begin at most this far along its way (kMaxStartM)
    double run_min_share = 0.0;      // and run on through bins with this share of their mean points
    CellKey section = kLookSection;  // the key of the section plane it makes
    bool free_only = true;           // false: samples that planes took count too
  };
  // What gather() found: the points' moments about the corner, and their extent.
  struct Gathered {
    PointMoments moments;
    double reach_min_m = 0.0;
    double reach_max_m = 0.0;
    double z_min_m = 0.0;
    double z_max_m = 0.0;
  };
  // A plane found near the corner: samples in its slab and box are its own, not the new
  // wall's (a blurred wall's shoulders, the ground, a roof).
  struct NearPlane {
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    double d_m = 0.0;
    double slab_m = 0.0;
    Eigen::Vector3d box_min_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d box_max_m = Eigen::Vector3d::Zero();
  };
  static constexpr std::size_t kMaxNearPlanes = 32;
  static constexpr double kBinM = 0.5;
  static constexpr std::size_t kBins = 64;

  // Which way from a wall is into its building: the side with (almost) no returns in front of
  // it, for inside a building a laser sees nothing, while in front of it lie the street, its
  // ground and what stands there. +1 along its normal, -1 against, 0 when unclear.
  int way_inside(const msg::PlanePatch& wall, const Eigen::Vector3d& out,
                 const Eigen::Vector3d& side, const Extent& ends, const Extent& heights) noexcept;
  // False when a wall found already stands at the corner; else `corner.reach_m` ends at the
  // building's far side when a wall found there faces the corner.
  [[nodiscard]] bool open_corner(std::span<const msg::PlanePatch> planes,
                                 Corner& corner) const noexcept;
  // True when a wall found already stands square to the corner's wall within kStepClearM of
  // the corner and beside it: the building turns there (the end of a blurred wall lies up to a
  // metre or two short of its corner), so it does not step back.
  [[nodiscard]] static bool side_near(std::span<const msg::PlanePatch> planes,
                                      const Corner& corner) noexcept;
  // The planes whose boxes reach into the corner's region, at most kMaxNearPlanes; the region
  // reaches `across_m` either side of the corner's way.
  [[nodiscard]] std::size_t near_planes(std::span<const msg::PlanePatch> planes,
                                        const Corner& corner, double across_m,
                                        std::span<NearPlane, kMaxNearPlanes> near) const noexcept;
  // The samples near the plane n . (p - corner) = offset_m: at most band_m from it, between
  // the corner's reach_from_m and reach_to_m along its way, within its heights, outside the
  // near planes' slabs. take_as >= 0: they become the look's (their owner). points_per_bin
  // counts their points by distance along the way, in kBinM bins from kBehindM behind.
  Gathered gather(const Corner& corner, const Eigen::Vector3d& normal, double offset_m,
                  double band_m, double reach_to_m, std::span<const NearPlane> near,
                  std::int32_t take_as, std::span<float, kBins> points_per_bin) noexcept;
  // The rounds of fitting at a corner, and what their last fit is.
  struct CornerFit {
    PlaneFit fit;
    Gathered gathered;  // the points of the last band
    Eigen::Vector3d normal = Eigen::Vector3d::UnitX();
    double offset_m = 0.0;
    double band_m = 0.0;
    double reach_to_m = 0.0;
    bool wall_like = false;  // enough points, long enough, flat enough
    bool upright = false;
  };
  CornerFit fit_corner(const Corner& corner, double noise_rmse_m,
                       std::span<const NearPlane> near) noexcept;
  // Tries one corner; true when a wall was found there (its section plane in `found_plane`).
  bool try_corner(const Corner& corner, double noise_rmse_m, std::span<const NearPlane> near,
                  SectionPlane& found_plane) noexcept;
  // At a corner where no side was found: the depths into the building at which the free
  // samples beyond the wall's end are denser than either side, nearest first; how many.
  static constexpr std::size_t kMaxStepDepths = 4;
  std::size_t step_depths(std::span<const msg::PlanePatch> planes, const Corner& corner,
                          std::span<double, kMaxStepDepths> depths_m) noexcept;
  // Tries a wall set back by each of step_depths() in turn, parallel to the corner's wall and
  // running on beyond its end; true when one was found (its section plane in `found_plane`).
  bool try_step(std::span<const msg::PlanePatch> planes, const Corner& corner, double noise_rmse_m,
                SectionPlane& found_plane) noexcept;

  const PlanesConfig& config_;
  VoxelGrid* voxels_ = nullptr;
};

}  // namespace blockmap::planes
