// libFuzzer target: the point cloud readers (`planes`, `buildings`) over arbitrary bytes, the
// first byte choosing the format. A file that is not a cloud must be a CloudFileError, never
// a crash, a hang or an allocation its size does not pay for (scripts/fuzz's RSS limit).
#include <cstdint>
#include <span>

#include "blockmap/hal/cloud/point_cloud_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using blockmap::hal::cloud::CloudFileError;
  using blockmap::hal::cloud::CloudFormat;
  if (size == 0) {
    return 0;
  }
  constexpr std::uint8_t kFormats = 5;
  const auto format = static_cast<CloudFormat>(data[0] % kFormats);
  try {
    static_cast<void>(blockmap::hal::cloud::parse_point_cloud(
        std::span<const std::uint8_t>(data + 1, size - 1), format));
  } catch (const CloudFileError&) {
    // Refused, naming why: what a damaged file must get.
  }
  return 0;
}
