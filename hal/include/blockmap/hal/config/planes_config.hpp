// The [planes] table of a configuration file: every PlanesConfig parameter, by the same name.
// Keys left out keep their defaults; an unknown key, a wrong type or a value the detector
// cannot use is a ConfigError naming it. config/planes.toml lists them all with the defaults.
#pragma once

#include <filesystem>
#include <string_view>

#include "blockmap/planes/planes_config.hpp"

namespace blockmap::hal::config {

// A document whose [planes] table (when present) overrides `base` (the defaults, or the
// mapper's window_planes_config()). Other top-level tables are left to their own readers.
[[nodiscard]] planes::PlanesConfig parse_planes_config(std::string_view text,
                                                       std::string_view source,
                                                       const planes::PlanesConfig& base = {});

// The same, from a file.
[[nodiscard]] planes::PlanesConfig load_planes_config(const std::filesystem::path& path,
                                                      const planes::PlanesConfig& base = {});

}  // namespace blockmap::hal::config
