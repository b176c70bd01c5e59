#include "blockmap/buildings/buildings_config.hpp"

#include <cmath>

namespace blockmap::buildings {
namespace {

bool positive(double value) {
  return std::isfinite(value) && value > 0.0;
}

bool non_negative(double value) {
  return std::isfinite(value) && value >= 0.0;
}

}  // namespace

std::string validate(const BuildingsConfig& config) {
  const struct {
    const char* key;
    double value;
    bool may_be_zero;
  } lengths[] = {
      {"min_wall_length_m", config.min_wall_length_m, false},
      {"min_low_wall_support_per_m", config.min_low_wall_support_per_m, true},
      {"corner_gap_m", config.corner_gap_m, false},
      {"collinear_offset_m", config.collinear_offset_m, false},
      {"max_occlusion_gap_m", config.max_occlusion_gap_m, true},
      {"parallel_merge_offset_m", config.parallel_merge_offset_m, true},
      {"fit_tolerance_m", config.fit_tolerance_m, false},
      {"min_notch_m", config.min_notch_m, false},
      {"l_penalty_m", config.l_penalty_m, true},
      {"t_penalty_m", config.t_penalty_m, true},
      {"min_virtual_gap_m", config.min_virtual_gap_m, true},
      {"min_block_area_m2", config.min_block_area_m2, false},
      {"min_block_wall_m", config.min_block_wall_m, true},
      {"block_wall_reach_m", config.block_wall_reach_m, false},
      {"block_column_m", config.block_column_m, false},
      {"block_step_m", config.block_step_m, false},
      {"block_min_band_m", config.block_min_band_m, true},
      {"block_snap_m", config.block_snap_m, true},
  };
  for (const auto& length : lengths) {
    if (length.may_be_zero ? !non_negative(length.value) : !positive(length.value)) {
      return std::string(length.key) + (length.may_be_zero ? ": must be >= 0" : ": must be > 0");
    }
  }
  if (!(config.corner_angle_tolerance_deg > 0.0 && config.corner_angle_tolerance_deg < 45.0)) {
    return "corner_angle_tolerance_deg: must be in (0, 45)";
  }
  if (!(config.collinear_angle_tolerance_deg > 0.0 &&
        config.collinear_angle_tolerance_deg < 45.0)) {
    return "collinear_angle_tolerance_deg: must be in (0, 45)";
  }
  if (!(config.min_explained_share >= 0.0 && config.min_explained_share <= 1.0)) {
    return "min_explained_share: must be in [0, 1]";
  }
  if (config.max_walls == 0 || config.max_walls > (1U << 20)) {
    return "max_walls: must be in [1, 1048576]";
  }
  if (config.max_buildings == 0 || config.max_buildings > 65535) {
    return "max_buildings: must be in [1, 65535]";
  }
  if (config.max_blocks == 0 || config.max_blocks > 1000) {
    return "max_blocks: must be in [1, 1000]";
  }
  return {};
}

}  // namespace blockmap::buildings
