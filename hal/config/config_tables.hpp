// One reader per table of a configuration file, each beside the defaults of the configuration
// it fills: keys left out keep what the configuration held, and an unknown key, a wrong type
// or a value the stage cannot use is a ConfigError naming it. The readers of the whole files
// (parse_planes_config, parse_mapper_config, ...) call them. Private to hal/config.
#pragma once

#include "blockmap/buildings/buildings_config.hpp"
#include "blockmap/localize/scan_matcher.hpp"
#include "blockmap/map/free_space_grid.hpp"
#include "blockmap/map/plane_registry.hpp"
#include "blockmap/map/scan_projector.hpp"
#include "blockmap/map/voxel_window.hpp"
#include "blockmap/planes/planes_config.hpp"
#include "toml_reader.hpp"

namespace blockmap::hal::config {

// t: the table as read from the file; c: the configuration it fills.

void read_planes_table(TableReader& t, planes::PlanesConfig& c);
void read_buildings_table(TableReader& t, buildings::BuildingsConfig& c);
// voxel_size_m: the window's voxels (the detector's samples), which its tiles must hold whole.
void read_window_table(TableReader& t, double voxel_size_m, map::VoxelWindowConfig& c);
void read_projection_table(TableReader& t, map::ScanProjectorConfig& c);
void read_free_space_table(TableReader& t, map::FreeSpaceConfig& c);
void read_registry_table(TableReader& t, map::PlaneRegistryConfig& c);
void read_scan_matching_table(TableReader& t, localize::ScanMatchConfig& c);

}  // namespace blockmap::hal::config
