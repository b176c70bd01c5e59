// Test support for codecs: feed a capture in different chunkings, and damage it the ways a
// cable does (flipped bits, lost bytes, cut-off telegrams, line noise). Deterministic: every
// random choice comes from a seeded generator.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <random>
#include <span>
#include <vector>

namespace blockmap::testing {

enum class Chunking { kWhole, kByteByByte, kRandom };

// Calls feed(chunk) over consecutive chunks of `bytes` that together are `bytes`.
template <typename Feed>
void feed_in_chunks(std::span<const std::uint8_t> bytes, Chunking chunking, std::uint32_t seed,
                    Feed&& feed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<std::size_t> size(1, 97);
  std::size_t position = 0;
  while (position < bytes.size()) {
    std::size_t length = bytes.size() - position;
    if (chunking == Chunking::kByteByByte) {
      length = 1;
    } else if (chunking == Chunking::kRandom) {
      length = std::min(length, size(random));
    }
    feed(bytes.subspan(position, length));
    position += length;
  }
}

inline std::vector<std::uint8_t> flip_random_bits(std::vector<std::uint8_t> bytes,
                                                  std::size_t flips, std::uint32_t seed) {
  std::mt19937 random(seed);
  if (bytes.empty()) {
    return bytes;
  }
  std::uniform_int_distribution<std::size_t> where(0, bytes.size() - 1);
  std::uniform_int_distribution<int> bit(0, 7);
  for (std::size_t i = 0; i < flips; ++i) {
    bytes[where(random)] ^= static_cast<std::uint8_t>(1U << bit(random));
  }
  return bytes;
}

inline std::vector<std::uint8_t> drop_random_bytes(const std::vector<std::uint8_t>& bytes,
                                                   double probability, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::bernoulli_distribution drop(probability);
  std::vector<std::uint8_t> kept;
  kept.reserve(bytes.size());
  for (std::uint8_t byte : bytes) {
    if (!drop(random)) {
      kept.push_back(byte);
    }
  }
  return kept;
}

inline std::vector<std::uint8_t> random_garbage(std::size_t length, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<std::uint8_t> garbage(length);
  for (auto& b : garbage) {
    b = static_cast<std::uint8_t>(byte(random));
  }
  return garbage;
}

inline std::vector<std::uint8_t> concat(
    std::initializer_list<std::span<const std::uint8_t>> parts) {
  std::vector<std::uint8_t> joined;
  for (const auto& part : parts) {
    joined.insert(joined.end(), part.begin(), part.end());
  }
  return joined;
}

inline std::vector<std::uint8_t> bytes_of(std::string_view text) {
  return {text.begin(), text.end()};
}

}  // namespace blockmap::testing
