// libFuzzer target: the NMEA decoder over arbitrary bytes. Besides memory errors (ASan, UBSan)
// it checks what the decoder promises: progress on every push, decoded values in range, and
// the same sentences whether the input arrives whole or in chunks.
#include <cstdint>
#include <span>

#include "blockmap/hal/protocol/nmea.hpp"
#include "require.hpp"

namespace {

using blockmap::hal::protocol::nmea::Decoder;

using blockmap::fuzz::require;

// Decodes `bytes` in chunks of `chunk` bytes; returns a digest of what was decoded.
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
      if (step.sentence != nullptr) {
        const auto& fix = step.sentence->fix;
        require(!fix.has_position || (fix.latitude_deg >= -90.0 && fix.latitude_deg <= 90.0 &&
                                      fix.longitude_deg >= -180.0 && fix.longitude_deg <= 180.0));
        require(!fix.has_time ||
                (fix.utc_milliseconds_of_day >= 0 && fix.utc_milliseconds_of_day < 86'402'000));
        digest = digest * 31 + step.sentence->start_offset +
                 7 * static_cast<std::uint64_t>(step.sentence->type);
      }
      if (step.rejected) {
        digest = digest * 37 + step.start_offset + static_cast<std::uint64_t>(step.reason);
      }
    }
  }
  return digest ^ decoder.drops().total();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) {
    return 0;
  }
  const std::span<const std::uint8_t> bytes(data, size);
  const std::uint64_t whole = decode(bytes, size);
  require(decode(bytes, 1) == whole);
  require(decode(bytes, 1 + data[0] % 13) == whole);
  return 0;
}
