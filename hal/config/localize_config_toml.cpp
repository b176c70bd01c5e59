// The localization tables: [scan_matching].
#include <cstdint>
#include <string>

#include "config_tables.hpp"
#include "toml_reader.hpp"

namespace blockmap::hal::config {

void read_scan_matching_table(TableReader& t, localize::ScanMatchConfig& c) {
  // Each level laser's scan matched against the grid of the scans before it: poses rigid
  // over seconds, where GPS alone bends the walls (docs/localize.md, Scan matching).
  c.enabled = t.boolean_or("enabled", c.enabled);
  c.cell_m = t.positive_or("cell_m", c.cell_m);
  c.cells_across = static_cast<std::uint32_t>(t.capacity_or("cells_across", c.cells_across));
  c.levels = static_cast<std::uint32_t>(t.capacity_or("levels", c.levels));
  c.iterations = static_cast<std::uint32_t>(t.capacity_or("iterations", c.iterations));
  c.min_height_m = t.number_or("min_height_m", c.min_height_m);
  c.max_height_m = t.number_or("max_height_m", c.max_height_m);
  c.point_spacing_m = t.non_negative_or("point_spacing_m", c.point_spacing_m);
  c.max_match_range_m = t.positive_or("max_match_range_m", c.max_match_range_m);
  c.map_update_m = t.non_negative_or("map_update_m", c.map_update_m);
  c.map_update_rad = t.non_negative_or("map_update_rad", c.map_update_rad);
  c.forget_after_m = t.non_negative_or("forget_after_m", c.forget_after_m);
  c.join_gap_m = t.non_negative_or("join_gap_m", c.join_gap_m);
  c.normal_neighbour_m = t.positive_or("normal_neighbour_m", c.normal_neighbour_m);
  c.max_points = static_cast<std::uint32_t>(t.capacity_or("max_points", c.max_points));
  c.min_points = static_cast<std::uint32_t>(t.capacity_or("min_points", c.min_points));
  c.min_overlap = t.in_range("min_overlap", t.number_or("min_overlap", c.min_overlap), 0.0, 1.0);
  c.max_step_m = t.positive_or("max_step_m", c.max_step_m);
  c.max_step_rad = t.positive_or("max_step_rad", c.max_step_rad);
  c.anchor_time_s = t.non_negative_or("anchor_time_s", c.anchor_time_s);
  c.yaw_rate_bias_time_s = t.non_negative_or("yaw_rate_bias_time_s", c.yaw_rate_bias_time_s);
  c.anchor_heading_lever_m = t.non_negative_or("anchor_heading_lever_m", c.anchor_heading_lever_m);
  c.prior_along_ratio = t.positive_or("prior_along_ratio", c.prior_along_ratio);
  c.prior_weight = t.positive_or("prior_weight", c.prior_weight);
  t.finish();
  if (const std::string problem = localize::validate(c); !problem.empty()) {
    t.reject(problem);
  }
}

}  // namespace blockmap::hal::config
