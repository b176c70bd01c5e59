// The [window] and [projection] tables of a mapping configuration (blockmap run/replay
// --config): the sliding window's tiles and sample capacity, and the band of laser ranges the
// mapper keeps. A vehicle whose laser sees the block's far facades from across a wide street
// (the UAL loop: 35-45 m) needs a wider window and range than the paper's Segway on a campus.
// Keys left out keep their defaults; an unknown key, a wrong type or a value the mapper
// cannot use is a ConfigError naming it. config/README.md lists them with the defaults.
#pragma once

#include <filesystem>
#include <string_view>

#include "blockmap/pipeline/mapper.hpp"

namespace blockmap::hal::config {

// A document whose [window] and [projection] tables (when present) override `base`'s window
// and projection. Other top-level tables are left to their own readers.
[[nodiscard]] pipeline::MapperConfig parse_window_config(std::string_view text,
                                                         std::string_view source,
                                                         const pipeline::MapperConfig& base);

[[nodiscard]] pipeline::MapperConfig load_window_config(const std::filesystem::path& path,
                                                        const pipeline::MapperConfig& base);

}  // namespace blockmap::hal::config
