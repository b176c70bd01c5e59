// Planes from points, the paper's way (section III and the start of IV of the seed paper):
//   points -> voxel samples (moments) -> local shape of each sample
//   -> for each small overlapping section: a fixed-grid Hough transform over (d, theta, phi),
//      every cell above the threshold that is a local maximum is a plane
//   -> each plane refitted by least squares to its inlier samples (PlaneRefiner, below)
//   -> section planes merged into the map's planes (PlaneMerger) and labelled.
// Everything is sized at init() from the configuration; add_point() and detect() allocate
// nothing. The same points in the same order give the same planes, bit for bit.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "blockmap/planes/hough_accumulator.hpp"
#include "blockmap/planes/orientation_grid.hpp"
#include "blockmap/planes/plane_merger.hpp"
#include "blockmap/planes/planes_config.hpp"
#include "blockmap/planes/section_cache.hpp"
#include "blockmap/planes/section_grid.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::planes {

struct DetectionStats {
  std::uint64_t points = 0;          // accepted into samples
  std::uint64_t points_dropped = 0;  // non-finite, out of range or no room (see counters)
  std::uint64_t overflows = 0;       // sections, section samples or planes beyond a capacity
  std::uint64_t samples = 0;
  std::uint64_t planar_samples = 0;
  std::uint64_t linear_samples = 0;
  std::uint64_t scattered_samples = 0;
  std::uint64_t sections = 0;
  std::uint64_t sections_searched = 0;  // with enough free points to hold a plane
  std::uint64_t sections_replayed = 0;  // of those, as they were last time (SectionCache)
  // of those, barren last time and grown too little since (barren_section_growth)
  std::uint64_t sections_still_barren = 0;
  // of those, gave planes last time and grown too little since (settled_section_growth)
  std::uint64_t sections_settled = 0;
  std::uint64_t votes = 0;
  std::uint64_t peaks = 0;
  std::uint64_t section_planes = 0;
  std::uint64_t samples_taken = 0;  // by section planes (each sample once)
  std::uint64_t planes = 0;
  std::uint64_t planes_excluded = 0;    // known not to be surfaces (set_exclusions)
  std::uint64_t corners_looked_at = 0;  // wall ends the corner look tried (CornerLook)
  std::uint64_t corner_walls = 0;       // walls it found there (sides and steps)
  double surface_noise_m = 0.0;         // VoxelGrid::surface_noise_m(): how blurred the cloud is
  std::uint64_t shapes_reused = 0;      // samples whose fine shape was kept (keep_shapes)
};

class PlaneDetector {
 public:
  // Takes every buffer from the arena. CHECK-fails on an invalid configuration (validate()).
  void init(Arena& arena, const PlanesConfig& config);
  // An arena budget that init() always fits in, for this configuration (an upper bound:
  // the orientation grid's exact size is only known once built).
  [[nodiscard]] static std::size_t arena_budget_bytes(const PlanesConfig& config) noexcept;

  // Forgets all points.
  void clear() noexcept;
  void add_point(const Eigen::Vector3f& point_m) noexcept { voxels_.add_point(point_m); }
  void add_points(std::span<const Eigen::Vector3f> points_m) noexcept;
  // A voxel's sums gathered elsewhere (the mapper's window), in the voxel grid's layout.
  void add_sample(const VoxelSums& sample) noexcept { voxels_.add_sums(sample); }
  // A sample as it is now (keep_shapes: the next detect() estimates shapes again only around
  // the samples set or added since the last one).
  void set_sample(const VoxelSums& sample) noexcept { voxels_.set_sums(sample); }
  // A hint that `key` is set or added soon: its slot is fetched.
  void prefetch_sample(CellKey key) const noexcept { voxels_.prefetch(key); }
  // A sample gone with all its points (a tile left the window).
  void remove_sample(CellKey key) noexcept { voxels_.erase(key); }

  // Planes known not to be surfaces (a laser's scan plane), dropped by the next detect()s.
  void set_exclusions(std::span<const PlaneExclusion> exclusions) noexcept;

  // The planes of every point added since clear(), largest first. The span stays valid
  // until the next detect() or clear().
  std::span<const msg::PlanePatch> detect() noexcept;

  // The moments (frame origin) of the points behind each plane of the last detect().
  [[nodiscard]] std::span<const PointMoments> plane_moments() const noexcept {
    return merger_.plane_moments();
  }
  [[nodiscard]] const DetectionStats& stats() const noexcept { return stats_; }
  [[nodiscard]] const PlanesConfig& config() const noexcept { return config_; }
  [[nodiscard]] const VoxelGrid& voxels() const noexcept { return voxels_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  void detect_in_section(std::size_t index) noexcept;
  // A section that gave no plane last time, whose free points have grown by less than
  // barren_section_growth since it was searched: not searched again yet.
  [[nodiscard]] bool still_barren(const SectionCache::Entry& before,
                                  std::uint64_t free_points) const noexcept;
  // A section that gave planes last time, whose free points have not shrunk and have grown
  // by less than settled_section_growth since it was searched.
  [[nodiscard]] bool settled(const SectionCache::Entry& before,
                             std::uint64_t free_points) const noexcept;
  // Gives a settled section's last planes again and takes again the samples it took that
  // are still there and free; returns whether it took any.
  bool replay_settled_section(const SectionCache::Entry& before, CellKey section,
                              std::span<const std::uint32_t> blocks) noexcept;
  // The section's Hough transform: votes, peaks, and each peak refined into a plane.
  void search_section(CellKey section, std::span<const std::uint32_t> blocks) noexcept;
  // A section whose inputs are last time's (SectionCache): its planes and samples again.
  void replay_section(const SectionCache::Entry& before, CellKey section,
                      std::span<const std::uint32_t> blocks) noexcept;
  // A sample taken by a plane of `section`: it neither votes nor counts for later sections.
  void take_sample(Voxel& voxel, std::int32_t owner, CellKey section) noexcept;
  // take_sample() without the cache's record (a replay: the cache took it again itself).
  void claim_sample(Voxel& voxel, std::int32_t owner) noexcept;
  // Whether a sample votes at all (the local-shape mode skips scattered samples).
  [[nodiscard]] bool votes(const Voxel& voxel) const noexcept;
  void vote_sample(const Voxel& voxel, const Eigen::Vector3f& position_m) noexcept;
  // PlaneRefiner: the inliers of a peak, refitted by least squares; false when too few.
  // The free samples of the section within band_m of the plane (planar ones facing it, and
  // scattered ones only when take_scattered), and their moments about centre_m.
  void select_inliers(const Eigen::Vector3f& normal, float d_m, float band_m, bool take_scattered,
                      const Eigen::Vector3d& centre_m, std::size_t sample_count,
                      PointMoments& moments, std::size_t& inliers) noexcept;
  bool refine(const HoughPeak& peak, const Eigen::Vector3f& section_centre_m,
              std::size_t sample_count, SectionPlane& out) noexcept;
  [[nodiscard]] bool orientation_searched(const Eigen::Vector3d& normal) const noexcept;
  // from_line: the plane is a wall seen as a line (walls_from_lines), a voxel high at least.
  void set_corners(const Eigen::Vector3d& normal, double d_m, std::size_t inlier_count,
                   bool from_line, SectionPlane& out) const noexcept;

  PlanesConfig config_;
  OrientationGrid orientations_;
  VoxelGrid voxels_;
  SectionGrid sections_;
  HoughAccumulator accumulator_;
  PlaneMerger merger_;
  SectionCache cache_;
  bool caching_ = false;               // keep_shapes with small enough sections
  std::uint64_t exclusions_salt_ = 0;  // of the exclusions refine() asks (walls_from_lines)
  std::span<std::uint32_t> block_free_points_;  // points of unclaimed voting samples, per block
  std::span<std::uint32_t> section_samples_;
  std::span<Eigen::Vector3f> section_positions_;
  std::span<std::uint32_t> inliers_;
  std::span<HoughPeak> peaks_;
  float cos_inlier_angle_ = 0.0f;
  DetectionStats stats_;
};

}  // namespace blockmap::planes
