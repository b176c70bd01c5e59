// Every parameter of plane detection, with defaults that work for a Segway with LMS2xx lasers
// in a city block (centimetre range noise, points 1-50 m away). Units are in the names.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "blockmap/planes/cell_index.hpp"

namespace blockmap::planes {

// Which plane orientations the Hough transform searches.
enum class OrientationMode : std::uint8_t {
  // The paper's: walls are vertical and roofs or ground horizontal, each within
  // orientation_tolerance_deg. The search space shrinks to two bands of the sphere.
  kWallsAndRoofs,
  // Any orientation, on cells of about equal area over the half sphere.
  kAny,
};

// How each sample votes.
enum class VotingMode : std::uint8_t {
  // A sample votes only for orientations near the normal of its neighbourhood (planar
  // samples) or on the circle of normals perpendicular to its line (samples on one scan
  // line); scattered samples (foliage) do not vote. Tens of votes per sample.
  kLocalShape,
  // The paper's literal transform: every sample votes for every orientation searched.
  kEveryOrientation,
};

struct PlanesConfig {
  // Points are first summed into cubic samples of this edge (moments, not points, are kept).
  double sample_size_m = 0.2;
  // Sections: cubes of section_size_m, one starting every section_stride_m() along each axis,
  // so that they overlap and a plane crossing a section border is whole in a neighbour.
  // section_size_m must be a whole multiple of the stride.
  double section_size_m = 1.6;
  // The stride is a block of samples: sections are made of the 4 x 4 x 4 blocks that the
  // voxel grid keeps.
  [[nodiscard]] double section_stride_m() const noexcept {
    return static_cast<double>(kBlockEdge) * sample_size_m;
  }

  // The (d, theta, phi) grid.
  double d_bin_m = 0.05;
  double angle_bin_deg = 2.0;
  OrientationMode orientation_mode = OrientationMode::kWallsAndRoofs;
  double orientation_tolerance_deg = 5.0;  // kWallsAndRoofs: off vertical / horizontal
  VotingMode voting_mode = VotingMode::kLocalShape;
  double normal_kernel_deg = 4.0;  // kLocalShape: planar samples vote this far around their normal

  // Local shape of a sample, from the points of its 3 x 3 x 3 neighbourhood.
  std::uint32_t min_points_for_shape = 5;
  double max_planarity_ratio = 0.3;  // sqrt(l0 / l1) of a planar neighbourhood, at most
  double max_line_ratio = 0.15;      // sqrt(l1 / l2) of a linear neighbourhood, at most
  // Scattered samples get a second look at the scale of 12 samples (walls blurred by pose
  // errors are flat at that scale).
  bool coarse_second_look = true;
  // The second look also takes a looser slab (sqrt(l0 / l1) up to max_noisy_slab_ratio) when
  // it is at most noisy_slab_per_noise times the cloud's surface noise thick (RMS): the
  // noise is measured on the surfaces found at the fine scale, so a crisp cloud's hedge stays
  // scattered while a cloud blurred by pose errors gets its walls back.
  double max_noisy_slab_ratio = 0.5;
  double noisy_slab_per_noise = 4.0;
  // Keep the samples' fine shapes from one detect() to the next until clear() (the mapper's
  // window, which changes a few per cent a second; VoxelGrid::keep_shapes). The batch tool
  // detects once and has no use for it. With it, a section whose samples and shapes are
  // as they were is not searched again either (SectionCache): the last
  // max_kept_sections searched sections are remembered.
  bool keep_shapes = false;
  std::size_t max_kept_sections = 16384;
  // With kept sections: a section whose last search found no plane is searched again only
  // once its free points (those of samples that vote and no earlier section took) have grown
  // by this fraction since; till then it is taken as barren still. 70 % of a mapper's
  // searches are such sections (ground swept by a pitching level laser, tree crowns), new
  // returns reach them scan after scan, and a few per cent more of the same makes no plane.
  // 0: searched again whenever anything in it changed, and the planes are those of a
  // detection afresh.
  double barren_section_growth = 0.25;
  // The same for a section that gave planes: while its free points lie between what they
  // were at its last search and that times (1 + settled_section_growth), it gives its last
  // planes again and takes again what it took that no earlier section took (new samples in
  // it stay free till it is searched again). 0: searched again whenever anything in it
  // changed.
  double settled_section_growth = 0.25;

  // A cell of the accumulator is a plane when its votes (points, summed over the cell and its
  // two neighbours in d) reach this threshold and no neighbouring cell has more.
  double min_votes = 30.0;
  std::size_t max_planes_per_section = 8;
  // Least-squares refinement: samples within this distance of a peak's plane, and (for
  // planar samples) with a normal within inlier_angle_deg of it, are its inliers. The band
  // widens to three times the fit's RMS distance when the plane is noisier (pose errors),
  // up to max_inlier_distance_m.
  double inlier_distance_m = 0.1;
  double max_inlier_distance_m = 0.4;
  double inlier_angle_deg = 20.0;
  std::uint32_t refine_iterations = 2;
  // A level 2D laser sees a wall as a horizontal line, whose points fit every plane through
  // it. With this set, such a line is the vertical plane through it (the paper's walls are
  // vertical; fit_plane_or_wall), and a plane that set_exclusions() names (the laser's own
  // scan plane, which holds all its points) is refused before it takes any sample. Off, a
  // line is not a plane. The mapper sets it when all its lasers are level.
  bool walls_from_lines = false;

  // Merging across sections (Tavares and Padilha): planes whose normals differ by at most
  // merge_angle_deg, whose centroids lie within merge_distance_m of each other's plane and
  // whose extents come within merge_gap_m plus merge_gap_fraction of the larger plane's size
  // (its bounding box diagonal) of each other are one plane.
  double merge_angle_deg = 5.0;
  double merge_distance_m = 0.15;
  double merge_gap_m = 2.0;
  double merge_gap_fraction = 0.15;

  // The corner look (CornerLook): after merging, the plane square to each wall through each
  // of its ends is tried, up to corner_reach_m into the building, for a side of it that the
  // votes missed (glimpsed through pose errors). It finds nothing more in a crisp cloud.
  // It runs when the cloud's surfaces are at least corner_look_min_noise_m thick (RMS; the
  // detector's surface noise): lasers alone give 2-6 mm, pose errors of a few tenths of a
  // degree 15-40 mm. In a crisp cloud the votes find what it would.
  bool corner_look = true;
  double corner_reach_m = 20.0;  // in [kMinCornerReachM, kMaxCornerReachM]
  double corner_look_min_noise_m = 0.01;

  // Labels. A plane within label_tolerance_deg of vertical is a wall when its observed extent
  // is at least min_wall_height_m high and min_wall_width_m wide; a horizontal one is ground
  // when it lies within ground_step_m of the ground (the lowest large horizontal plane), a
  // roof when it is at least min_roof_height_m above it. Everything else is "other".
  double label_tolerance_deg = 5.0;
  double min_wall_height_m = 1.8;
  double min_wall_width_m = 1.0;
  double ground_step_m = 0.5;
  double min_roof_height_m = 2.0;
  double min_reported_support = 50.0;  // smaller merged planes are not reported

  // Capacities, all taken at init.
  std::size_t max_samples = 1u << 20;
  // Occupied blocks of 4 x 4 x 4 samples; 0: as many as samples (always enough). A city scan
  // fills a block with 3-8 samples on average, so a memory-bound mapper sets it to a half.
  std::size_t max_blocks = 0;
  std::size_t max_samples_per_section = 4096;
  std::size_t max_patches = 1u << 16;
  std::size_t max_planes = 4096;
};

// The corner look's reach: at least the shortest wall it reports, at most its 64 bins of 0.5 m.
inline constexpr double kMinCornerReachM = 3.0;
inline constexpr double kMaxCornerReachM = 31.5;

// The block capacity: max_blocks, or max_samples when 0.
[[nodiscard]] constexpr std::size_t block_capacity(const PlanesConfig& config) noexcept {
  return config.max_blocks == 0 ? config.max_samples : config.max_blocks;
}

// Empty when the configuration is usable, otherwise what is wrong with it.
[[nodiscard]] std::string validate(const PlanesConfig& config);

}  // namespace blockmap::planes
