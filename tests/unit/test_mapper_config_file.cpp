// A mapping configuration file (hal/config/mapper_config.hpp) over a robot's mapper
// configuration: each table read by its own reader, what a stage is configured with derived
// from it, and each key the mapper cannot honour one line naming it.
#include <gtest/gtest.h>

#include <string>

#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/mapper_config.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/pipeline/mapper_config.hpp"

namespace blockmap::hal::config {
namespace {

pipeline::MapperConfig papers_robot() {
  return mapper_config_for(load_robot("paper_rmp"));
}

// An RMP with its one laser level: walls are lines.
pipeline::MapperConfig level_laser_robot() {
  pipeline::MapperConfig config = papers_robot();
  config.laser_count = 1;
  config.laser_mounts[0] = map::SensorMount{};
  return config;
}

std::string error_of(const std::string& text, const pipeline::MapperConfig& base) {
  try {
    static_cast<void>(parse_mapper_config(text, "map.toml", base));
  } catch (const ConfigError& error) {
    return error.what();
  }
  return "(no error)";
}

TEST(MapperConfigFile, EachTableFillsItsOwnStage) {
  const pipeline::MapperConfig c = parse_mapper_config(R"(
[planes]
sample_size_m = 0.25
section_size_m = 2.0
[buildings]
max_buildings = 32
[window]
tile_size_m = 10.0
max_samples = 100000
[projection]
max_range_m = 60.0
[scan_matching]
cell_m = 0.2
[registry]
max_final_planes = 4096
[mapper]
extract_every_s = 2.0
)",
                                                       "map.toml", papers_robot());
  EXPECT_EQ(c.planes.sample_size_m, 0.25);
  EXPECT_EQ(c.buildings.max_buildings, 32u);
  EXPECT_EQ(c.window.tile_size_m, 10.0);
  EXPECT_EQ(c.projection.max_range_m, 60.0);
  EXPECT_EQ(c.scan_matching.cell_m, 0.2);
  EXPECT_EQ(c.registry.max_final_planes, 4096u);
  EXPECT_EQ(c.extract_every_s, 2.0);
  // Derived, one way: the window's voxels are the detector's samples, the detector holds the
  // window's samples, and the section stride is a block of samples.
  EXPECT_EQ(pipeline::window_config(c).voxel_size_m, 0.25);
  EXPECT_EQ(pipeline::detector_config(c).max_samples, 100000u);
  EXPECT_EQ(c.planes.section_stride_m(), 1.0);
  EXPECT_EQ(pipeline::validate(c), "");
}

TEST(MapperConfigFile, LeftOutKeysKeepTheRobotsConfiguration) {
  const pipeline::MapperConfig base = papers_robot();
  const pipeline::MapperConfig c = parse_mapper_config("", "map.toml", base);
  EXPECT_EQ(c.laser_count, base.laser_count);
  EXPECT_EQ(c.window.max_samples, base.window.max_samples);
  EXPECT_EQ(c.projection.far_ground_range_m, base.projection.far_ground_range_m);
}

TEST(MapperConfigFile, WhatTheMapperDerivesIsRefusedNamingTheKey) {
  const pipeline::MapperConfig base = papers_robot();
  EXPECT_EQ(error_of("[planes]\nmax_samples = 1000\n", base),
            "map.toml: planes.max_samples: the mapper's detector holds the window's samples: set "
            "[window] max_samples");
  EXPECT_NE(error_of("[planes]\nsection_stride_m = 0.8\n", base).find("planes.section_stride_m"),
            std::string::npos);
  EXPECT_EQ(error_of("[planes]\nmax_blocks = 100000\n", base),
            "map.toml: planes.max_blocks: must be at most [window] max_samples (0: a sixth of "
            "them)");
}

TEST(MapperConfigFile, TheRigidPathPlacesTheMatchersFrame) {
  // With the rigid path (the paper's robot's default) the matcher's frame is not laid onto
  // the filter's path as the run goes: a key that asks for it is refused, naming it.
  const pipeline::MapperConfig c = parse_mapper_config("", "map.toml", papers_robot());
  ASSERT_TRUE(pipeline::solves_the_path(c));
  EXPECT_EQ(pipeline::matcher_config(c).anchor_time_s, 0.0);
  EXPECT_NE(error_of("[scan_matching]\nanchor_time_s = 60.0\n", papers_robot())
                .find("map.toml: scan_matching.anchor_time_s: the rigid path places"),
            std::string::npos);
  // Without the rigid path the anchor is the matcher's own, and the key is honoured.
  const pipeline::MapperConfig anchored =
      parse_mapper_config("[rigid_path]\nenabled = false\n[scan_matching]\nanchor_time_s = 60.0\n",
                          "map.toml", papers_robot());
  EXPECT_FALSE(pipeline::solves_the_path(anchored));
  EXPECT_EQ(pipeline::matcher_config(anchored).anchor_time_s, 60.0);
}

TEST(MapperConfigFile, TheLoopClosureTableIsReadAndCheckedAndItsTypoRefused) {
  const pipeline::MapperConfig c = parse_mapper_config(
      "[loop_closure]\nmax_candidates = 2\nmin_score = 0.7\n[rigid_path]\nmax_closures = 16\n",
      "map.toml", papers_robot());
  EXPECT_EQ(c.loop_closure.max_candidates, 2u);
  EXPECT_EQ(c.loop_closure.min_score, 0.7);
  EXPECT_EQ(c.path.max_closures, 16u);
  EXPECT_NE(error_of("[loop_closure]\nmax_candidates = 9\n", papers_robot()).find("max_candidates"),
            std::string::npos);
  EXPECT_NE(error_of("[loop_closure]\nmin_scor = 0.7\n", papers_robot()).find("min_scor"),
            std::string::npos);
  EXPECT_EQ(error_of("[loop_closure]\nenabled = false\n", papers_robot()), "(no error)");
}

TEST(MapperConfigFile, ThePriorMapTableIsReadButAMapTurnsItOn) {
  const pipeline::MapperConfig c = parse_mapper_config(
      "[prior_map]\nparticles = 128\nhit_sigma_m = 0.3\nrestart_after = 3\n"
      "frame_sigma_m = 0.0\nframe_time_s = 90.0\n",
      "map.toml", papers_robot());
  EXPECT_EQ(c.prior_map.particles, 128u);
  EXPECT_EQ(c.prior_map.hit_sigma_m, 0.3);
  EXPECT_EQ(c.prior_map.restart_after, 3u);
  EXPECT_EQ(c.prior_map.frame_sigma_m, 0.0) << "a survey's map: placings hold the path as they are";
  EXPECT_EQ(c.prior_map.frame_time_s, 90.0);
  EXPECT_NE(error_of("[prior_map]\nframe_time_s = 0.0\n", papers_robot()).find("frame_time_s"),
            std::string::npos);
  EXPECT_NE(error_of("[prior_map]\nframe_sigma_m = -1.0\n", papers_robot()).find("frame_sigma_m"),
            std::string::npos);
  EXPECT_FALSE(c.prior_map.enabled) << "replay --prior-map turns it on";
  EXPECT_NE(error_of("[prior_map]\nparticles = 4\n", papers_robot()).find("particles"),
            std::string::npos);
  EXPECT_NE(error_of("[prior_map]\nunmapped_share = 1.5\n", papers_robot()).find("unmapped_share"),
            std::string::npos);
  EXPECT_NE(error_of("[prior_map]\nenabled = true\n", papers_robot()).find("enabled"),
            std::string::npos);
}

TEST(MapperConfigFile, ALevelOnlyRobotCannotTurnWallsFromLinesOff) {
  EXPECT_NE(error_of("[planes]\nwalls_from_lines = false\n", level_laser_robot())
                .find("planes.walls_from_lines"),
            std::string::npos);
  // The paper's robot has a vertical laser too: its walls are planes, and the key is its own.
  EXPECT_EQ(error_of("[planes]\nwalls_from_lines = false\n", papers_robot()), "(no error)");
}

TEST(MapperConfigFile, AWindowThatDoesNotHoldWholeBlocksOfSamplesIsRefused) {
  EXPECT_NE(error_of("[window]\ntile_size_m = 7.0\n", papers_robot()).find("tile_size_m"),
            std::string::npos);
}

}  // namespace
}  // namespace blockmap::hal::config
