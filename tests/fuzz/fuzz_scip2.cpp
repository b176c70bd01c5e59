// libFuzzer target: the Hokuyo SCIP 2.0 decoder over arbitrary bytes: progress on every push,
// scans within their capacity and consistent with their echo, and the same replies whole or
// chunked.
#include <cstdint>
#include <span>

#include "blockmap/hal/protocol/hokuyo_scip2.hpp"
#include "require.hpp"

namespace {

using blockmap::hal::protocol::hokuyo_scip2::Decoder;

using blockmap::fuzz::require;

std::uint64_t decode(std::span<const std::uint8_t> bytes, std::size_t chunk) {
  Decoder decoder;
  std::uint64_t digest = 0;
  while (!bytes.empty()) {
    std::span<const std::uint8_t> piece = bytes.first(std::min(chunk, bytes.size()));
    bytes = bytes.subspan(piece.size());
    while (!piece.empty()) {
      const Decoder::Step step = decoder.push(piece, 0);
      require(step.consumed > 0 && step.consumed <= piece.size());
      piece = piece.subspan(step.consumed);
      if (step.scan != nullptr) {
        require(step.reply != nullptr);
        require(step.scan->beam_count <= blockmap::msg::kMaxLaserBeams);
        for (std::size_t i = 0; i < step.scan->beam_count; ++i) {
          require(step.scan->ranges_m[i] >= 0.0F && step.scan->ranges_m[i] < 262.2F);
          digest = digest * 3 + static_cast<std::uint64_t>(step.scan->ranges_m[i] * 1000.0F);
        }
      }
      if (step.reply != nullptr)
        digest = digest * 31 + step.reply->echo.size() + step.reply->body.size();
      if (step.rejected) digest = digest * 37 + static_cast<std::uint64_t>(step.reason);
    }
  }
  return digest ^ decoder.drops().total();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::span<const std::uint8_t> bytes(data, size);
  const std::uint64_t whole = decode(bytes, size);
  require(decode(bytes, 1) == whole);
  require(decode(bytes, 1 + data[0] % 17) == whole);
  return 0;
}
