// The one error every configuration reader throws: its message is a single line naming the
// file and the key ("usc_block.toml: buildings[1].height_m: must be > 0"), printed as is by the
// command line before anything starts.
#pragma once

#include <stdexcept>
#include <string>

namespace blockmap::hal {

class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace blockmap::hal
