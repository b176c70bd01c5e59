#include "blockmap/planes/planes_config.hpp"

#include <cmath>

namespace blockmap::planes {
namespace {

// A refit converges in two or three; more is a typing error that would run for hours.
constexpr std::uint32_t kMaxRefineIterations = 100;

bool whole_multiple(double a, double b) {
  const double ratio = a / b;
  return ratio >= 1.0 - 1e-9 && std::abs(ratio - std::round(ratio)) < 1e-6;
}

// The samples, the sections and the Hough grid.
std::string validate_grids(const PlanesConfig& c) {
  if (!(c.sample_size_m > 0.0)) {
    return "sample_size_m must be > 0";
  }
  if (!whole_multiple(c.section_size_m, c.section_stride_m())) {
    return "section_size_m must be a whole multiple of the section stride (4 x sample_size_m)";
  }
  if (std::lround(c.section_size_m / c.section_stride_m()) > 4) {
    return "section_size_m may be at most 4 strides (each point is in (size/stride)^3 sections)";
  }
  if (!(c.d_bin_m > 0.0) || c.d_bin_m > c.section_size_m) {
    return "d_bin_m must be > 0 and at most section_size_m";
  }
  if (!(c.angle_bin_deg >= 0.25 && c.angle_bin_deg <= 30.0)) {
    return "angle_bin_deg must be in [0.25, 30]";
  }
  if (!(c.orientation_tolerance_deg >= 0.0 && c.orientation_tolerance_deg < 45.0)) {
    return "orientation_tolerance_deg must be in [0, 45)";
  }
  return {};
}

// Who votes, and what a peak needs.
std::string validate_votes(const PlanesConfig& c) {
  if (!(c.normal_kernel_deg > 0.0 && c.normal_kernel_deg <= 30.0)) {
    return "normal_kernel_deg must be in (0, 30]";
  }
  if (!(c.max_planarity_ratio > 0.0 && c.max_planarity_ratio <= 1.0) ||
      !(c.max_line_ratio > 0.0 && c.max_line_ratio <= 1.0)) {
    return "max_planarity_ratio and max_line_ratio must be in (0, 1]";
  }
  if (!(c.max_noisy_slab_ratio > 0.0 && c.max_noisy_slab_ratio <= 1.0) ||
      !(c.noisy_slab_per_noise >= 0.0 && c.noisy_slab_per_noise <= 100.0)) {
    return "max_noisy_slab_ratio must be in (0, 1] and noisy_slab_per_noise in [0, 100]";
  }
  if (!(c.min_votes >= 3.0)) {
    return "min_votes must be >= 3";
  }
  if (c.max_planes_per_section < 1 || c.max_planes_per_section > 64) {
    return "max_planes_per_section must be in [1, 64]";
  }
  return {};
}

// Refitting, merging, the corner look and the labels.
std::string validate_fitting(const PlanesConfig& c) {
  if (!(c.max_inlier_distance_m >= c.inlier_distance_m)) {
    return "max_inlier_distance_m must be at least inlier_distance_m";
  }
  if (c.refine_iterations < 1 || c.refine_iterations > kMaxRefineIterations) {
    return "refine_iterations must be in [1, 100]";
  }
  if (!(c.inlier_distance_m > 0.0) || !(c.inlier_angle_deg > 0.0 && c.inlier_angle_deg <= 90.0)) {
    return "inlier_distance_m must be > 0 and inlier_angle_deg in (0, 90]";
  }
  if (!(c.merge_angle_deg > 0.0 && c.merge_angle_deg < 45.0) || !(c.merge_distance_m > 0.0) ||
      !(c.merge_gap_m >= 0.0) || !(c.merge_gap_fraction >= 0.0 && c.merge_gap_fraction <= 1.0)) {
    return "merge_angle_deg must be in (0, 45), merge_distance_m > 0, merge_gap_m >= 0, "
           "merge_gap_fraction in [0, 1]";
  }
  if (!(c.corner_reach_m >= kMinCornerReachM && c.corner_reach_m <= kMaxCornerReachM)) {
    return "corner_reach_m must be in [3, 31.5]";
  }
  if (!(c.corner_look_min_noise_m >= 0.0)) {
    return "corner_look_min_noise_m must be >= 0";
  }
  if (!(c.barren_section_growth >= 0.0 && c.barren_section_growth <= 100.0)) {
    return "barren_section_growth must be in [0, 100]";
  }
  if (!(c.settled_section_growth >= 0.0 && c.settled_section_growth <= 100.0)) {
    return "settled_section_growth must be in [0, 100]";
  }
  if (!(c.label_tolerance_deg > 0.0 && c.label_tolerance_deg < 45.0)) {
    return "label_tolerance_deg must be in (0, 45)";
  }
  return {};
}

// What the arena holds.
std::string validate_capacities(const PlanesConfig& c) {
  if (c.max_samples < 1 || c.max_samples_per_section < 1 || c.max_patches < 1 || c.max_planes < 1 ||
      (c.keep_shapes && c.max_kept_sections < 1)) {
    return "capacities must be >= 1";
  }
  if (c.max_samples >= (std::size_t{1} << 31) || c.max_patches >= (std::size_t{1} << 31)) {
    return "max_samples and max_patches must be < 2^31";
  }
  if (c.max_blocks > c.max_samples) {
    return "max_blocks must be at most max_samples (0: as many)";
  }
  if (c.max_patches < c.max_planes) {
    return "max_patches must be >= max_planes";
  }
  return {};
}

}  // namespace

std::string validate(const PlanesConfig& c) {
  for (const auto check : {validate_grids, validate_votes, validate_fitting, validate_capacities}) {
    if (std::string problem = check(c); !problem.empty()) {
      return problem;
    }
  }
  return {};
}

}  // namespace blockmap::planes
