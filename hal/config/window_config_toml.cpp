#include "blockmap/hal/config/window_config.hpp"

#include "toml_reader.hpp"

namespace blockmap::hal::config {

pipeline::MapperConfig parse_window_config(std::string_view text, std::string_view source,
                                           const pipeline::MapperConfig& base) {
  const toml::table document = parse_document(text, source);
  TableReader root(document, std::string(source), "");
  pipeline::MapperConfig c = base;
  if (auto table = root.table("window")) {
    TableReader& t = *table;
    c.window.tile_size_m = t.positive_or("tile_size_m", c.window.tile_size_m);
    const std::int64_t tiles = t.integer_or("tiles_across", c.window.tiles_across);
    if (tiles < 3 || tiles > 255 || tiles % 2 == 0) {
      t.fail("tiles_across", "must be odd, from 3 to 255 (the robot's tile is the middle one)");
    }
    c.window.tiles_across = static_cast<std::uint32_t>(tiles);
    c.window.max_samples = t.capacity_or("max_samples", c.window.max_samples);
    const std::int64_t core = t.integer_or("core_tiles_across", c.window.core_tiles_across);
    if (core < 0 || core > tiles || (core != 0 && core % 2 == 0)) {
      t.fail("core_tiles_across", "must be 0 (every tile) or odd and at most tiles_across");
    }
    c.window.core_tiles_across = static_cast<std::uint32_t>(core);
    c.window.reserve_samples = t.capacity_or("reserve_samples", c.window.reserve_samples);
    t.finish();
    // The tile must hold whole 4-voxel blocks of the detector's samples ([planes] sample_size_m).
    map::VoxelWindowConfig window = c.window;
    window.voxel_size_m = c.planes.sample_size_m;
    if (const std::string problem = map::validate(window); !problem.empty()) {
      throw ConfigError(std::string(source) + ": " + problem);
    }
  }
  if (auto table = root.table("projection")) {
    TableReader& t = *table;
    c.projection.min_range_m = t.non_negative_or("min_range_m", c.projection.min_range_m);
    c.projection.max_range_m = t.positive_or("max_range_m", c.projection.max_range_m);
    if (!(c.projection.max_range_m > c.projection.min_range_m)) {
      t.fail("max_range_m", "must be more than min_range_m");
    }
    c.projection.far_ground_range_m =
        t.non_negative_or("far_ground_range_m", c.projection.far_ground_range_m);
    c.projection.ground_band_m = t.non_negative_or("ground_band_m", c.projection.ground_band_m);
    t.finish();
  }
  if (auto table = root.table("free_space")) {
    TableReader& t = *table;
    // Where the level lasers saw through: blocks the robot drove around are traced in it.
    const std::int64_t tiles = t.integer_or("tiles_across", c.free_space.tiles_across);
    if (tiles < 0 || tiles > 64) {
      t.fail("tiles_across", "must be from 0 (off) to 64 (tiles of 32 cells)");
    }
    c.free_space.tiles_across = static_cast<std::uint32_t>(tiles);
    c.free_space.cell_size_m = t.positive_or("cell_size_m", c.free_space.cell_size_m);
    c.free_space.stop_short_m = t.non_negative_or("stop_short_m", c.free_space.stop_short_m);
    t.finish();
    if (const std::string problem = map::validate(c.free_space); !problem.empty()) {
      throw ConfigError(std::string(source) + ": " + problem);
    }
  }
  if (auto table = root.table("rigid_path")) {
    TableReader& t = *table;
    // The whole run's path at once, and the final planes moved with it (docs/localize.md,
    // The whole path at once).
    // Left out: on wherever scans are matched. Given: asked for, or off.
    if (t.has("enabled")) {
      c.rigid_path =
          t.boolean_or("enabled", false) ? pipeline::RigidPath::kOn : pipeline::RigidPath::kOff;
    }
    // The stream shows the planes where the latest solve puts them (false: as drawn until
    // the end), reported again when that moves one more than view_change_m.
    c.rigid_view = t.boolean_or("view", c.rigid_view);
    c.rigid_view_change_m = t.positive_or("view_change_m", c.rigid_view_change_m);
    localize::PathSmootherConfig& r = c.path;
    r.max_keyframes = t.capacity_or("max_keyframes", r.max_keyframes);
    r.keyframe_spacing_m = t.positive_or("keyframe_spacing_m", r.keyframe_spacing_m);
    r.along_sigma_per_sqrt_m = t.positive_or("along_sigma_per_sqrt_m", r.along_sigma_per_sqrt_m);
    r.across_sigma_per_sqrt_m = t.positive_or("across_sigma_per_sqrt_m", r.across_sigma_per_sqrt_m);
    r.yaw_sigma_per_sqrt_m = t.positive_or("yaw_sigma_per_sqrt_m", r.yaw_sigma_per_sqrt_m);
    r.yaw_sigma_per_sqrt_s = t.positive_or("yaw_sigma_per_sqrt_s", r.yaw_sigma_per_sqrt_s);
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
    t.finish();
    if (const std::string problem = localize::validate(r); !problem.empty()) {
      throw ConfigError(std::string(source) + ": " + problem);
    }
  }
  if (auto table = root.table("scan_matching")) {
    TableReader& t = *table;
    // Each level laser's scan matched against the grid of the scans before it: poses rigid
    // over seconds, where GPS alone bends the walls (docs/localize.md, Scan matching).
    localize::ScanMatchConfig& m = c.scan_matching;
    m.enabled = t.boolean_or("enabled", m.enabled);
    m.cell_m = t.positive_or("cell_m", m.cell_m);
    m.cells_across = static_cast<std::uint32_t>(t.capacity_or("cells_across", m.cells_across));
    m.levels = static_cast<std::uint32_t>(t.capacity_or("levels", m.levels));
    m.iterations = static_cast<std::uint32_t>(t.capacity_or("iterations", m.iterations));
    m.min_height_m = t.number_or("min_height_m", m.min_height_m);
    m.max_height_m = t.number_or("max_height_m", m.max_height_m);
    m.point_spacing_m = t.non_negative_or("point_spacing_m", m.point_spacing_m);
    m.max_match_range_m = t.positive_or("max_match_range_m", m.max_match_range_m);
    m.map_update_m = t.non_negative_or("map_update_m", m.map_update_m);
    m.map_update_rad = t.non_negative_or("map_update_rad", m.map_update_rad);
    m.join_gap_m = t.non_negative_or("join_gap_m", m.join_gap_m);
    m.normal_neighbour_m = t.positive_or("normal_neighbour_m", m.normal_neighbour_m);
    m.max_points = static_cast<std::uint32_t>(t.capacity_or("max_points", m.max_points));
    m.min_points = static_cast<std::uint32_t>(t.capacity_or("min_points", m.min_points));
    m.min_overlap = t.in_range("min_overlap", t.number_or("min_overlap", m.min_overlap), 0.0, 1.0);
    m.max_step_m = t.positive_or("max_step_m", m.max_step_m);
    m.max_step_rad = t.positive_or("max_step_rad", m.max_step_rad);
    m.anchor_time_s = t.non_negative_or("anchor_time_s", m.anchor_time_s);
    m.anchor_heading_lever_m =
        t.non_negative_or("anchor_heading_lever_m", m.anchor_heading_lever_m);
    m.prior_along_ratio = t.positive_or("prior_along_ratio", m.prior_along_ratio);
    m.prior_weight = t.positive_or("prior_weight", m.prior_weight);
    t.finish();
    if (const std::string problem = localize::validate(m); !problem.empty()) {
      throw ConfigError(std::string(source) + ": " + problem);
    }
  }
  if (auto table = root.table("registry")) {
    TableReader& t = *table;
    // The plane registry's capacities (docs/mapper.md, Memory): the planes in the window, and
    // those that left it, which a long mission over new ground fills.
    c.registry.max_live_planes = t.capacity_or("max_live_planes", c.registry.max_live_planes);
    c.registry.max_final_planes = t.capacity_or("max_final_planes", c.registry.max_final_planes);
    t.finish();
    if (const std::string problem = map::validate(c.registry); !problem.empty()) {
      throw ConfigError(std::string(source) + ": " + problem);
    }
  }
  if (auto table = root.table("mapper")) {
    TableReader& t = *table;
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
  return c;
}

pipeline::MapperConfig load_window_config(const std::filesystem::path& path,
                                          const pipeline::MapperConfig& base) {
  return parse_window_config(read_config_file(path), path.string(), base);
}

}  // namespace blockmap::hal::config
