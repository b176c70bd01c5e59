// libFuzzer target: the SICK CoLa decoder (A, B and detection) over arbitrary bytes: progress,
// scans within capacity with finite ranges, and the same events whole or chunked.
#include <cmath>
#include <cstdint>
#include <span>

#include "blockmap/hal/protocol/sick_cola.hpp"
#include "require.hpp"

namespace {

namespace cola = blockmap::hal::protocol::sick_cola;

using blockmap::fuzz::require;

std::uint64_t digest_of(const cola::Decoder::Step& step) {
  std::uint64_t digest = (step.rejected ? 1000 + static_cast<std::uint64_t>(step.reason) : 0);
  if (step.telegram != nullptr) {
    digest = digest * 31 + step.telegram->start_offset + step.telegram->payload.size() +
             step.telegram->type.size();
  }
  if (step.scan != nullptr) {
    require(step.scan->beam_count <= blockmap::msg::kMaxLaserBeams);
    for (std::size_t i = 0; i < step.scan->beam_count; ++i) {
      require(std::isfinite(step.scan->ranges_m[i]));
      digest = digest * 3 + static_cast<std::uint64_t>(std::fabs(step.scan->ranges_m[i]) * 1000.0F);
    }
  }
  return digest;
}

std::uint64_t decode(std::span<const std::uint8_t> bytes, std::size_t chunk,
                     cola::Framing framing) {
  cola::Config config;
  config.framing = framing;
  cola::StaticDecoder<4096> decoder(config);
  std::uint64_t digest = 0;
  std::size_t idle = 0;
  while (!bytes.empty()) {
    std::span<const std::uint8_t> piece = bytes.first(std::min(chunk, bytes.size()));
    bytes = bytes.subspan(piece.size());
    for (;;) {
      const cola::Decoder::Step step = decoder.push(piece, 0);
      require(step.consumed <= piece.size());
      piece = piece.subspan(step.consumed);
      if (!step.has_event()) {
        require(piece.empty());
        break;
      }
      idle = step.consumed == 0 ? idle + 1 : 0;
      require(idle < 20000);  // held bytes are delivered, not looped on
      digest = digest * 131 + digest_of(step);
    }
  }
  for (cola::Decoder::Step step = decoder.flush(); step.has_event(); step = decoder.flush()) {
    digest = digest * 131 + digest_of(step);
  }
  return digest ^ decoder.drops().total();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto framing = static_cast<cola::Framing>(data[0] % 3);
  const std::span<const std::uint8_t> bytes(data, size);
  const std::uint64_t whole = decode(bytes, size, framing);
  require(decode(bytes, 1, framing) == whole);
  require(decode(bytes, 1 + data[0] % 31, framing) == whole);
  return 0;
}
