// libFuzzer target: the SICK LMS2xx decoder over arbitrary bytes: progress on every call,
// scans within capacity and with finite ranges, and the same events whole or chunked.
#include <cmath>
#include <cstdint>
#include <span>

#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "require.hpp"

namespace {

namespace lms = blockmap::hal::protocol::sick_lms2xx;

using blockmap::fuzz::require;

std::uint64_t digest_of(const lms::Decoder::Step& step) {
  std::uint64_t digest = static_cast<std::uint64_t>(step.event) * 7 + step.offset;
  if (step.event == lms::Decoder::Event::kTelegram) {
    const lms::Telegram& t = *step.telegram;
    digest = digest * 31 + t.command + t.data.size() + t.start_offset;
    if (t.has_scan) {
      require(t.scan.beam_count <= blockmap::msg::kMaxLaserBeams);
      for (std::size_t i = 0; i < t.scan.beam_count; ++i) {
        require(std::isfinite(t.scan.ranges_m[i]) && t.scan.ranges_m[i] >= 0.0F);
        digest = digest * 3 + static_cast<std::uint64_t>(t.scan.ranges_m[i] * 1000.0F);
      }
    }
  }
  if (step.event == lms::Decoder::Event::kRejected)
    digest = digest * 37 + static_cast<std::uint64_t>(step.reason);
  return digest;
}

std::uint64_t decode(std::span<const std::uint8_t> bytes, std::size_t chunk, lms::Config config) {
  lms::Decoder decoder(config);
  std::uint64_t digest = 0;
  std::size_t idle_calls = 0;
  while (!bytes.empty()) {
    std::span<const std::uint8_t> piece = bytes.first(std::min(chunk, bytes.size()));
    bytes = bytes.subspan(piece.size());
    for (;;) {
      const lms::Decoder::Step step = decoder.push(piece, 0);
      require(step.consumed <= piece.size());
      piece = piece.subspan(step.consumed);
      if (step.event == lms::Decoder::Event::kNone) {
        require(piece.empty());
        break;
      }
      idle_calls = step.consumed == 0 ? idle_calls + 1 : 0;
      require(idle_calls < 4 * lms::kMaxTelegramBytes);  // replays end
      digest = digest * 131 + digest_of(step);
    }
  }
  for (lms::Decoder::Step step = decoder.flush(); step.event != lms::Decoder::Event::kNone;
       step = decoder.flush()) {
    digest = digest * 131 + digest_of(step);
  }
  return digest ^ decoder.drops().total();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  lms::Config config;
  config.range_bits = static_cast<std::uint8_t>(13 + data[0] % 3);
  config.require_reply_address = (data[0] & 0x80) == 0;
  const std::span<const std::uint8_t> bytes(data, size);
  const std::uint64_t whole = decode(bytes, size, config);
  require(decode(bytes, 1, config) == whole);
  require(decode(bytes, 1 + data[0] % 29, config) == whole);
  return 0;
}
