// A mapping configuration file (blockmap run/replay and the daemon, --config): every table
// the mapper's stages read, over the mapper's configuration for the robot: [planes],
// [buildings], [window], [projection], [free_space], [rigid_path], [scan_matching],
// [registry] and [mapper]. A vehicle whose laser sees the block's far facades from across a
// wide street (the UAL loop: 35-45 m) needs a wider window and range than the paper's Segway
// on a campus. Keys left out keep their defaults; an unknown key, a wrong type or a value the
// mapper cannot use is a ConfigError naming it. config/README.md lists them with the defaults.
#pragma once

#include <filesystem>
#include <string_view>

#include "blockmap/pipeline/mapper.hpp"

namespace blockmap::hal::config {

// A document whose tables (when present) override `base`'s. Other top-level tables are left
// to their own readers.
[[nodiscard]] pipeline::MapperConfig parse_mapper_config(std::string_view text,
                                                         std::string_view source,
                                                         const pipeline::MapperConfig& base);

[[nodiscard]] pipeline::MapperConfig load_mapper_config(const std::filesystem::path& path,
                                                        const pipeline::MapperConfig& base);

}  // namespace blockmap::hal::config
