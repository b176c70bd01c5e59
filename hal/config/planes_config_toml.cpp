#include "blockmap/hal/config/planes_config.hpp"

#include "config_tables.hpp"
#include "toml_reader.hpp"

namespace blockmap::hal::config {

void read_planes_table(TableReader& t, planes::PlanesConfig& c) {
  c.sample_size_m = t.number_or("sample_size_m", c.sample_size_m);
  c.section_size_m = t.number_or("section_size_m", c.section_size_m);
  if (t.has("section_stride_m")) {
    t.fail("section_stride_m",
           "is 4 x sample_size_m (the samples' 4 x 4 x 4 blocks): set "
           "sample_size_m");
  }
  c.d_bin_m = t.number_or("d_bin_m", c.d_bin_m);
  c.angle_bin_deg = t.number_or("angle_bin_deg", c.angle_bin_deg);
  const std::string orientation = t.string_or("orientations", "walls_and_roofs");
  if (orientation == "walls_and_roofs") {
    c.orientation_mode = planes::OrientationMode::kWallsAndRoofs;
  } else if (orientation == "any") {
    c.orientation_mode = planes::OrientationMode::kAny;
  } else {
    t.fail("orientations", R"(must be "walls_and_roofs" or "any")");
  }
  c.orientation_tolerance_deg =
      t.number_or("orientation_tolerance_deg", c.orientation_tolerance_deg);
  const std::string voting = t.string_or("voting", "local_shape");
  if (voting == "local_shape") {
    c.voting_mode = planes::VotingMode::kLocalShape;
  } else if (voting == "every_orientation") {
    c.voting_mode = planes::VotingMode::kEveryOrientation;
  } else {
    t.fail("voting", R"(must be "local_shape" or "every_orientation")");
  }
  c.normal_kernel_deg = t.number_or("normal_kernel_deg", c.normal_kernel_deg);
  c.min_points_for_shape =
      static_cast<std::uint32_t>(t.capacity_or("min_points_for_shape", c.min_points_for_shape));
  c.max_planarity_ratio = t.number_or("max_planarity_ratio", c.max_planarity_ratio);
  c.max_line_ratio = t.number_or("max_line_ratio", c.max_line_ratio);
  c.coarse_second_look = t.boolean_or("coarse_second_look", c.coarse_second_look);
  c.max_noisy_slab_ratio = t.number_or("max_noisy_slab_ratio", c.max_noisy_slab_ratio);
  c.noisy_slab_per_noise = t.number_or("noisy_slab_per_noise", c.noisy_slab_per_noise);
  c.walls_from_lines = t.boolean_or("walls_from_lines", c.walls_from_lines);
  c.barren_section_growth = t.number_or("barren_section_growth", c.barren_section_growth);
  c.settled_section_growth = t.number_or("settled_section_growth", c.settled_section_growth);
  c.min_votes = t.number_or("min_votes", c.min_votes);
  c.max_planes_per_section = t.capacity_or("max_planes_per_section", c.max_planes_per_section);
  c.inlier_distance_m = t.number_or("inlier_distance_m", c.inlier_distance_m);
  c.max_inlier_distance_m = t.number_or("max_inlier_distance_m", c.max_inlier_distance_m);
  c.inlier_angle_deg = t.number_or("inlier_angle_deg", c.inlier_angle_deg);
  c.refine_iterations =
      static_cast<std::uint32_t>(t.capacity_or("refine_iterations", c.refine_iterations));
  c.merge_angle_deg = t.number_or("merge_angle_deg", c.merge_angle_deg);
  c.merge_distance_m = t.number_or("merge_distance_m", c.merge_distance_m);
  c.merge_gap_m = t.number_or("merge_gap_m", c.merge_gap_m);
  c.merge_gap_fraction = t.number_or("merge_gap_fraction", c.merge_gap_fraction);
  c.corner_look = t.boolean_or("corner_look", c.corner_look);
  c.corner_reach_m = t.number_or("corner_reach_m", c.corner_reach_m);
  c.corner_look_min_noise_m = t.number_or("corner_look_min_noise_m", c.corner_look_min_noise_m);
  c.label_tolerance_deg = t.number_or("label_tolerance_deg", c.label_tolerance_deg);
  c.min_wall_height_m = t.number_or("min_wall_height_m", c.min_wall_height_m);
  c.min_wall_width_m = t.number_or("min_wall_width_m", c.min_wall_width_m);
  c.ground_step_m = t.number_or("ground_step_m", c.ground_step_m);
  c.min_roof_height_m = t.number_or("min_roof_height_m", c.min_roof_height_m);
  c.min_reported_support = t.number_or("min_reported_support", c.min_reported_support);
  c.max_samples = t.capacity_or("max_samples", c.max_samples);
  if (const std::int64_t blocks =
          t.integer_or("max_blocks", static_cast<std::int64_t>(c.max_blocks));
      blocks < 0) {
    t.fail("max_blocks",
           "must be >= 0 (0: as many as max_samples; in the mapper a quarter of the window's)");
  } else {
    c.max_blocks = static_cast<std::size_t>(blocks);
  }
  c.max_samples_per_section = t.capacity_or("max_samples_per_section", c.max_samples_per_section);
  c.max_patches = t.capacity_or("max_patches", c.max_patches);
  c.max_planes = t.capacity_or("max_planes", c.max_planes);
  t.finish();
  if (const std::string problem = planes::validate(c); !problem.empty()) {
    t.reject("planes: " + problem);
  }
}

planes::PlanesConfig parse_planes_config(std::string_view text, std::string_view source,
                                         const planes::PlanesConfig& base) {
  const toml::table document = parse_document(text, source);
  refuse_unknown_tables(document, source);
  TableReader root(document, std::string(source), "");
  planes::PlanesConfig c = base;
  if (auto table = root.table("planes")) {
    read_planes_table(*table, c);
  }
  return c;
}

planes::PlanesConfig load_planes_config(const std::filesystem::path& path,
                                        const planes::PlanesConfig& base) {
  return parse_planes_config(read_config_file(path), path.string(), base);
}

}  // namespace blockmap::hal::config
