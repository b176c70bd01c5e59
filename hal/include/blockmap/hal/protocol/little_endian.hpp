// Little-endian integers in byte spans, for the formats blockmap writes itself (byte logs,
// the binary plane stream). Whole spans: the value's width is the span's size (1 to 8 bytes).
#pragma once

#include <cstdint>
#include <span>

namespace blockmap::hal::protocol {

[[nodiscard]] inline std::uint64_t read_le(std::span<const std::uint8_t> bytes) noexcept {
  std::uint64_t value = 0;
  for (std::size_t i = bytes.size(); i-- > 0;) {
    value = (value << 8U) | bytes[i];
  }
  return value;
}

inline void write_le(std::uint64_t value, std::span<std::uint8_t> out) noexcept {
  for (std::uint8_t& byte : out) {
    byte = static_cast<std::uint8_t>(value & 0xFFU);
    value >>= 8U;
  }
}

}  // namespace blockmap::hal::protocol
