// Random numbers that are the same everywhere: one stream per noise source, each seeded from a
// run's seed and the source's name, so that changing one source does not change another's
// numbers. The generator (SplitMix64 seeding a xoshiro256**) and the Gaussian (Marsaglia's
// polar method) are written out, not taken from <random>, so that a seed gives the same
// numbers with every standard library: the simulator's bytes and the particle filter's
// trajectory then depend only on the seed and the machine's floating point.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <string_view>

namespace blockmap {

class Random {
 public:
  Random(std::uint64_t seed, std::string_view stream) noexcept {
    std::uint64_t state = seed ^ 0x9E3779B97F4A7C15ULL;
    for (const char c : stream) {  // FNV-1a of the stream name
      state = (state ^ static_cast<std::uint8_t>(c)) * 0x100000001B3ULL;
    }
    for (std::uint64_t& word : s_) {
      word = split_mix(state);
    }
  }

  std::uint64_t next() noexcept {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17U;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

  // Uniform in [0, 1).
  double uniform() noexcept { return static_cast<double>(next() >> 11U) * 0x1.0p-53; }
  double uniform(double low, double high) noexcept { return low + (high - low) * uniform(); }
  bool chance(double probability) noexcept { return uniform() < probability; }
  // Standard normal.
  double gaussian() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u = 0.0;
    double v = 0.0;
    double s = 0.0;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double factor = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * factor;
    has_spare_ = true;
    return u * factor;
  }
  double gaussian(double sigma) noexcept { return sigma * gaussian(); }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept {
    return (x << static_cast<unsigned>(k)) | (x >> static_cast<unsigned>(64 - k));
  }
  static std::uint64_t split_mix(std::uint64_t& state) noexcept {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31U);
  }

  std::array<std::uint64_t, 4> s_{};
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace blockmap
