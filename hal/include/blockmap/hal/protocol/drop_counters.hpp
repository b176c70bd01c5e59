// Per-reason drop counters for a protocol codec: every byte, frame or sentence a codec throws
// away is counted under the reason it was thrown away, so that health reporting can tell a
// noisy cable (garbage, bad checksums) from a misconfigured device (unsupported telegrams).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "blockmap/core/counter.hpp"

namespace blockmap::hal::protocol {

// Reason must be an enum whose last enumerator is kCount.
template <typename Reason>
requires std::is_enum_v<Reason>
class DropCounters {
 public:
  static constexpr std::size_t kReasons = static_cast<std::size_t>(Reason::kCount);

  void count(Reason reason, std::uint64_t amount = 1) noexcept {
    counters_[static_cast<std::size_t>(reason)].increment(amount);
  }
  [[nodiscard]] std::uint64_t value(Reason reason) const noexcept {
    return counters_[static_cast<std::size_t>(reason)].value();
  }
  [[nodiscard]] std::uint64_t total() const noexcept {
    std::uint64_t sum = 0;
    for (const MonotonicCounter& counter : counters_) {
      sum += counter.value();
    }
    return sum;
  }

 private:
  std::array<MonotonicCounter, kReasons> counters_{};
};

}  // namespace blockmap::hal::protocol
