// libFuzzer target: candump log lines and the Segway RMP decoder over arbitrary input. The
// input is read as text lines; each line that parses as a frame goes to the decoder, and every
// frame is also written back and re-parsed, which must give the same frame.
#include <cstdint>
#include <cstring>
#include <string_view>

#include "blockmap/hal/protocol/candump.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "require.hpp"

namespace {

namespace candump = blockmap::hal::protocol::candump;
namespace rmp = blockmap::hal::protocol::segway_rmp;

using blockmap::fuzz::require;

bool same_frame(const blockmap::hal::CanFrame& a, const blockmap::hal::CanFrame& b) {
  return a.id == b.id && a.extended == b.extended && a.remote == b.remote && a.error == b.error &&
         a.dlc == b.dlc && std::memcmp(a.data.data(), b.data.data(), a.dlc) == 0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  rmp::Decoder decoder;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    const std::string_view line = text.substr(start, end - start);
    start = end + 1;
    candump::Record record;
    const bool candump_line = candump::parse_line(line, record) == candump::ParseError::kNone;
    if (!candump_line && candump::parse_id_bytes_line(line, record) != candump::ParseError::kNone) {
      continue;
    }
    if (candump_line) {
      char written[64];
      const std::size_t length = candump::format_line(record, written);
      require(length > 0);
      candump::Record again;
      require(candump::parse_line(std::string_view(written, length), again) ==
              candump::ParseError::kNone);
      require(same_frame(record.frame, again.frame) && again.stamp_ns == record.stamp_ns);
    }
    const rmp::Decoder::Step step = decoder.push(record.frame, record.stamp_ns);
    require(step.cycle == nullptr || record.frame.id == rmp::kStatusLastId);
  }
  return 0;
}
