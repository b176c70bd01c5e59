// libFuzzer target: a plane list (`buildings INPUT.json`, `replay --prior-map`) over arbitrary
// text. Text that is not a plane list must be refused with an exception the command turns
// into one line (JSON's own, or std::invalid_argument), never a crash.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "outputs/plane_json.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const nlohmann::json document = nlohmann::json::parse(data, data + size);
    static_cast<void>(blockmap::cli::planes_from_json(document));
  } catch (const nlohmann::json::exception&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
