#include "blockmap/hal/config/mapper_config.hpp"

#include <cstdint>
#include <string>

#include "config_tables.hpp"
#include "toml_reader.hpp"

namespace blockmap::hal::config {
namespace {

// The whole run's path at once, and the final planes moved with it (docs/localize.md, The
// whole path at once).
void read_rigid_path_table(TableReader& t, pipeline::MapperConfig& c) {
  // Left out: on wherever scans are matched. Given: asked for, or off.
  if (t.has("enabled")) {
    c.rigid_path =
        t.boolean_or("enabled", false) ? pipeline::RigidPath::kOn : pipeline::RigidPath::kOff;
  }
  // The stream shows the planes where the latest solve puts them (false: as drawn until
  // the end), reported again when that moves one more than view_change_m.
  c.rigid_view = t.boolean_or("view", c.rigid_view);
  c.rigid_view_change_m = t.positive_or("view_change_m", c.rigid_view_change_m);
  c.rigid_join_finals = t.boolean_or("join_final_planes", c.rigid_join_finals);
  localize::PathSmootherConfig& r = c.path;
  r.max_keyframes = t.capacity_or("max_keyframes", r.max_keyframes);
  r.keyframe_spacing_m = t.positive_or("keyframe_spacing_m", r.keyframe_spacing_m);
  r.along_sigma_per_sqrt_m = t.positive_or("along_sigma_per_sqrt_m", r.along_sigma_per_sqrt_m);
  r.across_sigma_per_sqrt_m = t.positive_or("across_sigma_per_sqrt_m", r.across_sigma_per_sqrt_m);
  r.yaw_sigma_per_sqrt_m = t.positive_or("yaw_sigma_per_sqrt_m", r.yaw_sigma_per_sqrt_m);
  r.yaw_sigma_per_sqrt_s = t.positive_or("yaw_sigma_per_sqrt_s", r.yaw_sigma_per_sqrt_s);
  // Across the way and in the turn, where the scans were matched.
  r.matched_across_sigma_per_sqrt_m =
      t.positive_or("matched_across_sigma_per_sqrt_m", r.matched_across_sigma_per_sqrt_m);
  r.matched_yaw_sigma_per_sqrt_m =
      t.positive_or("matched_yaw_sigma_per_sqrt_m", r.matched_yaw_sigma_per_sqrt_m);
  r.bias_sigma_m = t.positive_or("bias_sigma_m", r.bias_sigma_m);
  r.bias_time_s = t.positive_or("bias_time_s", r.bias_time_s);
  r.fix_sigma_m = t.positive_or("fix_sigma_m", r.fix_sigma_m);
  // A carrier-phase (RTK) fix's sigma, per fix: no slow error is solved for it.
  r.rtk_fixed_sigma_m = t.positive_or("rtk_fixed_sigma_m", r.rtk_fixed_sigma_m);
  r.rtk_float_sigma_m = t.positive_or("rtk_float_sigma_m", r.rtk_float_sigma_m);
  r.iterations = static_cast<std::uint32_t>(t.capacity_or("iterations", r.iterations));
  // Ties between passes (0: none, the path's band alone).
  r.max_ties = static_cast<std::size_t>(t.non_negative(
      "max_ties",
      static_cast<double>(t.integer_or("max_ties", static_cast<std::int64_t>(r.max_ties)))));
  r.tie_offset_sigma_m = t.positive_or("tie_offset_sigma_m", r.tie_offset_sigma_m);
  r.tie_angle_sigma_deg = t.positive_or("tie_angle_sigma_deg", r.tie_angle_sigma_deg);
  r.tie_huber_sigmas = t.positive_or("tie_huber_sigmas", r.tie_huber_sigmas);
  r.tie_gate_deg = t.positive_or("tie_gate_deg", r.tie_gate_deg);
  r.cg_iterations = static_cast<std::uint32_t>(t.capacity_or("cg_iterations", r.cg_iterations));
  // Loop closures (0: none).
  r.max_closures = static_cast<std::size_t>(t.non_negative(
      "max_closures", static_cast<double>(t.integer_or(
                          "max_closures", static_cast<std::int64_t>(r.max_closures)))));
  r.closure_huber_sigmas = t.positive_or("closure_huber_sigmas", r.closure_huber_sigmas);
  t.finish();
  if (const std::string problem = localize::validate(r); !problem.empty()) {
    t.reject(problem);
  }
}

// Loop closing on the rigid path: submaps of the level scans matched against the earlier
// ones near them (docs/localize.md, Loop closing).
void read_loop_closure_table(TableReader& t, localize::LoopClosureConfig& l) {
  l.enabled = t.boolean_or("enabled", l.enabled);
  l.cell_m = t.positive_or("cell_m", l.cell_m);
  l.submap_length_m = t.positive_or("submap_length_m", l.submap_length_m);
  l.scan_spacing_m = t.non_negative_or("scan_spacing_m", l.scan_spacing_m);
  l.max_range_m = t.positive_or("max_range_m", l.max_range_m);
  l.join_gap_m = t.non_negative_or("join_gap_m", l.join_gap_m);
  l.max_submaps = t.capacity_or("max_submaps", l.max_submaps);
  l.max_cells_per_submap = t.capacity_or("max_cells_per_submap", l.max_cells_per_submap);
  l.max_query_points = t.capacity_or("max_query_points", l.max_query_points);
  l.grid_across = static_cast<std::uint32_t>(t.capacity_or("grid_across", l.grid_across));
  l.levels = static_cast<std::uint32_t>(t.capacity_or("levels", l.levels));
  l.candidate_distance_m = t.positive_or("candidate_distance_m", l.candidate_distance_m);
  l.min_travel_apart_m = t.non_negative_or("min_travel_apart_m", l.min_travel_apart_m);
  l.max_candidates = t.capacity_or("max_candidates", l.max_candidates);
  l.search_radius_m = t.positive_or("search_radius_m", l.search_radius_m);
  l.search_yaw_deg = t.non_negative_or("search_yaw_deg", l.search_yaw_deg);
  // Without fixes the window grows with the path driven between the two passes.
  l.search_radius_per_m = t.non_negative_or("search_radius_per_m", l.search_radius_per_m);
  l.search_yaw_deg_per_m = t.non_negative_or("search_yaw_deg_per_m", l.search_yaw_deg_per_m);
  l.max_search_radius_m = t.positive_or("max_search_radius_m", l.max_search_radius_m);
  l.max_search_yaw_deg = t.positive_or("max_search_yaw_deg", l.max_search_yaw_deg);
  l.min_score = t.positive_or("min_score", l.min_score);
  l.last_submap_min_m = t.non_negative_or("last_submap_min_m", l.last_submap_min_m);
  l.wide_search_radius_m = t.non_negative_or("wide_search_radius_m", l.wide_search_radius_m);
  l.wide_search_yaw_deg = t.non_negative_or("wide_search_yaw_deg", l.wide_search_yaw_deg);
  l.wide_min_score = t.positive_or("wide_min_score", l.wide_min_score);
  l.point_sigma_m = t.positive_or("point_sigma_m", l.point_sigma_m);
  l.floor_sigma_m = t.positive_or("floor_sigma_m", l.floor_sigma_m);
  l.floor_sigma_deg = t.positive_or("floor_sigma_deg", l.floor_sigma_deg);
  t.finish();
  if (const std::string problem = localize::validate(l); !problem.empty()) {
    t.reject(problem);
  }
}

// Monte Carlo localization against a prior 2D map (docs/localize.md, A prior map); `enabled`
// is set by a map being given (replay --prior-map), not here.
void read_prior_map_table(TableReader& t, localize::PriorMapConfig& m) {
  m.cell_m = t.positive_or("cell_m", m.cell_m);
  m.max_cells = t.capacity_or("max_cells", m.max_cells);
  m.margin_m = t.non_negative_or("margin_m", m.margin_m);
  m.particles = t.capacity_or("particles", m.particles);
  m.max_points = t.capacity_or("max_points", m.max_points);
  m.hit_sigma_m = t.positive_or("hit_sigma_m", m.hit_sigma_m);
  m.unmapped_share = t.positive_or("unmapped_share", m.unmapped_share);
  m.inside_share = t.positive_or("inside_share", m.inside_share);
  m.independent_points = t.positive_or("independent_points", m.independent_points);
  m.update_spacing_m = t.positive_or("update_spacing_m", m.update_spacing_m);
  m.update_turn_deg = t.positive_or("update_turn_deg", m.update_turn_deg);
  m.motion_sigma_m = t.non_negative_or("motion_sigma_m", m.motion_sigma_m);
  m.motion_sigma_per_m = t.non_negative_or("motion_sigma_per_m", m.motion_sigma_per_m);
  m.turn_sigma_deg = t.non_negative_or("turn_sigma_deg", m.turn_sigma_deg);
  m.turn_sigma_deg_per_m = t.non_negative_or("turn_sigma_deg_per_m", m.turn_sigma_deg_per_m);
  m.start_after_m = t.non_negative_or("start_after_m", m.start_after_m);
  m.start_sigma_m = t.non_negative_or("start_sigma_m", m.start_sigma_m);
  m.start_yaw_sigma_deg = t.non_negative_or("start_yaw_sigma_deg", m.start_yaw_sigma_deg);
  m.frame_sigma_m = t.non_negative_or("frame_sigma_m", m.frame_sigma_m);
  m.frame_time_s = t.positive_or("frame_time_s", m.frame_time_s);
  m.max_placing_sigma_m = t.positive_or("max_placing_sigma_m", m.max_placing_sigma_m);
  m.max_spread_m = t.positive_or("max_spread_m", m.max_spread_m);
  m.min_hit_share = t.non_negative_or("min_hit_share", m.min_hit_share);
  m.place_spacing_m = t.non_negative_or("place_spacing_m", m.place_spacing_m);
  m.min_sigma_m = t.positive_or("min_sigma_m", m.min_sigma_m);
  m.placing_gate_m = t.positive_or("placing_gate_m", m.placing_gate_m);
  m.restart_after = static_cast<std::uint32_t>(t.capacity_or("restart_after", m.restart_after));
  m.lost_after = static_cast<std::uint32_t>(t.capacity_or("lost_after", m.lost_after));
  t.finish();
  localize::PriorMapConfig checked = m;
  checked.enabled = true;
  if (const std::string problem = localize::validate(checked); !problem.empty()) {
    t.reject(problem);
  }
}

// The detector's table as the mapper reads it: the window sets its sample capacity, and a
// robot whose lasers are all level sees its walls as lines.
void read_mapper_planes_table(TableReader& t, pipeline::MapperConfig& c) {
  if (t.has("max_samples")) {
    t.fail("max_samples",
           "the mapper's detector holds the window's samples: set [window] "
           "max_samples");
  }
  const bool lines_set = t.has("walls_from_lines");
  read_planes_table(t, c.planes);
  if (lines_set && !c.planes.walls_from_lines && pipeline::only_level_lasers(c)) {
    t.fail("walls_from_lines",
           "the robot's lasers are all level: its walls are lines, so it "
           "cannot be false");
  }
}

void read_mapper_table(TableReader& t, pipeline::MapperConfig& c) {
  // Seconds of scan time between two plane extractions: the plane list's update period,
  // and most of the mapper's cost (docs/mapper.md, Speed).
  c.extract_every_s = t.positive_or("extract_every_s", c.extract_every_s);
  // Scans are drawn this many seconds late, with the particle filter's smoothed path
  // instead of its estimate of the moment: straight walls, a plane list as late.
  c.localizer.map_pose_lag_s = t.non_negative_or("pose_lag_s", c.localizer.map_pose_lag_s);
  if (const std::string problem = localize::validate(c.localizer); !problem.empty()) {
    t.fail("pose_lag_s", problem);
  }
  t.finish();
}

}  // namespace

pipeline::MapperConfig parse_mapper_config(std::string_view text, std::string_view source,
                                           const pipeline::MapperConfig& base) {
  const toml::table document = parse_document(text, source);
  refuse_unknown_tables(document, source);
  TableReader root(document, std::string(source), "");
  pipeline::MapperConfig c = base;
  if (auto table = root.table("planes")) {
    read_mapper_planes_table(*table, c);
  }
  if (auto table = root.table("buildings")) {
    read_buildings_table(*table, c.buildings);
  }
  if (auto table = root.table("window")) {
    read_window_table(*table, pipeline::window_config(c).voxel_size_m, c.window);
  }
  if (auto table = root.table("projection")) {
    read_projection_table(*table, c.projection);
  }
  if (auto table = root.table("free_space")) {
    read_free_space_table(*table, c.free_space);
  }
  if (auto table = root.table("rigid_path")) {
    read_rigid_path_table(*table, c);
  }
  if (auto table = root.table("loop_closure")) {
    read_loop_closure_table(*table, c.loop_closure);
  }
  if (auto table = root.table("prior_map")) {
    read_prior_map_table(*table, c.prior_map);
  }
  bool anchor_set = false;
  if (auto table = root.table("scan_matching")) {
    anchor_set = table->has("anchor_time_s");
    read_scan_matching_table(*table, c.scan_matching);
  }
  if (auto table = root.table("registry")) {
    read_registry_table(*table, c.registry);
  }
  if (auto table = root.table("mapper")) {
    read_mapper_table(*table, c);
  }
  if (anchor_set && pipeline::solves_the_path(c)) {
    throw ConfigError(std::string(source) +
                      ": scan_matching.anchor_time_s: the rigid path places the matcher's frame; "
                      "the anchor is for a mapper without it ([rigid_path] enabled = false)");
  }
  if (c.planes.max_blocks > c.window.max_samples) {
    throw ConfigError(std::string(source) +
                      ": planes.max_blocks: must be at most [window] max_samples (0: a sixth of "
                      "them)");
  }
  return c;
}

pipeline::MapperConfig load_mapper_config(const std::filesystem::path& path,
                                          const pipeline::MapperConfig& base) {
  return parse_mapper_config(read_config_file(path), path.string(), base);
}

}  // namespace blockmap::hal::config
