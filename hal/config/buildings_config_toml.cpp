#include "blockmap/hal/config/buildings_config.hpp"

#include "config_tables.hpp"
#include "toml_reader.hpp"

namespace blockmap::hal::config {

void read_buildings_table(TableReader& t, buildings::BuildingsConfig& c) {
  c.min_wall_length_m = t.number_or("min_wall_length_m", c.min_wall_length_m);
  c.use_low_walls = t.boolean_or("use_low_walls", c.use_low_walls);
  c.min_low_wall_support_per_m =
      t.number_or("min_low_wall_support_per_m", c.min_low_wall_support_per_m);
  c.corner_gap_m = t.number_or("corner_gap_m", c.corner_gap_m);
  c.corner_angle_tolerance_deg =
      t.number_or("corner_angle_tolerance_deg", c.corner_angle_tolerance_deg);
  c.collinear_angle_tolerance_deg =
      t.number_or("collinear_angle_tolerance_deg", c.collinear_angle_tolerance_deg);
  c.collinear_offset_m = t.number_or("collinear_offset_m", c.collinear_offset_m);
  c.max_occlusion_gap_m = t.number_or("max_occlusion_gap_m", c.max_occlusion_gap_m);
  c.parallel_merge_offset_m = t.number_or("parallel_merge_offset_m", c.parallel_merge_offset_m);
  c.fit_tolerance_m = t.number_or("fit_tolerance_m", c.fit_tolerance_m);
  c.min_notch_m = t.number_or("min_notch_m", c.min_notch_m);
  c.l_penalty_m = t.number_or("l_penalty_m", c.l_penalty_m);
  c.t_penalty_m = t.number_or("t_penalty_m", c.t_penalty_m);
  c.min_virtual_gap_m = t.number_or("min_virtual_gap_m", c.min_virtual_gap_m);
  c.min_explained_share = t.number_or("min_explained_share", c.min_explained_share);
  c.min_block_area_m2 = t.number_or("min_block_area_m2", c.min_block_area_m2);
  c.min_block_wall_m = t.number_or("min_block_wall_m", c.min_block_wall_m);
  c.block_wall_reach_m = t.number_or("block_wall_reach_m", c.block_wall_reach_m);
  c.block_column_m = t.number_or("block_column_m", c.block_column_m);
  c.block_step_m = t.number_or("block_step_m", c.block_step_m);
  c.block_min_band_m = t.number_or("block_min_band_m", c.block_min_band_m);
  c.block_snap_m = t.number_or("block_snap_m", c.block_snap_m);
  c.max_walls = t.capacity_or("max_walls", c.max_walls);
  c.max_buildings = t.capacity_or("max_buildings", c.max_buildings);
  c.max_blocks = t.capacity_or("max_blocks", c.max_blocks);
  t.finish();
  if (const std::string problem = buildings::validate(c); !problem.empty()) {
    t.reject("buildings: " + problem);
  }
}

buildings::BuildingsConfig parse_buildings_config(std::string_view text, std::string_view source,
                                                  const buildings::BuildingsConfig& base) {
  const toml::table document = parse_document(text, source);
  refuse_unknown_tables(document, source);
  TableReader root(document, std::string(source), "");
  buildings::BuildingsConfig c = base;
  if (auto table = root.table("buildings")) {
    read_buildings_table(*table, c);
  }
  return c;
}

buildings::BuildingsConfig load_buildings_config(const std::filesystem::path& path,
                                                 const buildings::BuildingsConfig& base) {
  return parse_buildings_config(read_config_file(path), path.string(), base);
}

}  // namespace blockmap::hal::config
