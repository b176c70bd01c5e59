// libFuzzer target: a `--config` file over arbitrary text, read by every reader a command
// uses (planes, buildings, run/replay's mapper, the daemon). A file that cannot be used must
// be a ConfigError naming why; one that is accepted must be valid, and its memory computable
// at once (the budget check runs before anything is allocated).
#include <cstdint>
#include <string_view>

#include "blockmap/hal/config/buildings_config.hpp"
#include "blockmap/hal/config/config_error.hpp"
#include "blockmap/hal/config/daemon_config.hpp"
#include "blockmap/hal/config/mapper_config.hpp"
#include "blockmap/hal/config/planes_config.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/pipeline/mapper.hpp"
#include "require.hpp"

namespace {

using blockmap::fuzz::require;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace config = blockmap::hal::config;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    static_cast<void>(config::parse_planes_config(text, "fuzz.toml", {}));
  } catch (const blockmap::hal::ConfigError&) {
  }
  try {
    static_cast<void>(config::parse_buildings_config(text, "fuzz.toml", {}));
  } catch (const blockmap::hal::ConfigError&) {
  }
  try {
    static_cast<void>(config::parse_daemon_config(text, "fuzz.toml"));
  } catch (const blockmap::hal::ConfigError&) {
  }
  try {
    const blockmap::pipeline::MapperConfig base = config::mapper_config_for(config::RobotSpec{});
    const blockmap::pipeline::MapperConfig mapper =
        config::parse_mapper_config(text, "fuzz.toml", base);
    if (blockmap::pipeline::validate(mapper).empty()) {
      require(blockmap::pipeline::Mapper::arena_bytes(mapper) > 0);
    }
  } catch (const blockmap::hal::ConfigError&) {
  }
  return 0;
}
