// The [buildings] table of a configuration file: every BuildingsConfig parameter, by the same
// name. Keys left out keep their defaults; an unknown key, a wrong type or a value the fitter
// cannot use is a ConfigError naming it. config/buildings.toml lists them with the defaults.
#pragma once

#include <filesystem>
#include <string_view>

#include "blockmap/buildings/buildings_config.hpp"

namespace blockmap::hal::config {

// A document whose [buildings] table (when present) overrides `base`. Other top-level tables
// are left to their own readers.
[[nodiscard]] buildings::BuildingsConfig parse_buildings_config(
    std::string_view text, std::string_view source, const buildings::BuildingsConfig& base = {});

[[nodiscard]] buildings::BuildingsConfig load_buildings_config(
    const std::filesystem::path& path, const buildings::BuildingsConfig& base = {});

}  // namespace blockmap::hal::config
