// A serial line as the host sees it: a device puts telegrams on the wire, each byte takes ten
// bit times at the line's rate, and the host's reads return what has arrived, every
// read_interval (a USB-serial adapter's latency timer, the tty's polling). Fixed capacity; a
// telegram that does not fit is refused and counted.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/time.hpp"

namespace blockmap::hal::sim {

class SerialWire {
 public:
  SerialWire(std::uint32_t baud, TimestampNs read_interval_ns, std::size_t capacity_bytes);

  // Puts `bytes` on the wire from `earliest_ns` or when the previous bytes are out, whichever
  // is later. False (and counted) when they do not fit the buffer.
  bool send(std::span<const std::uint8_t> bytes, TimestampNs earliest_ns);
  // When the wire is free again.
  [[nodiscard]] TimestampNs busy_until_ns() const noexcept { return busy_until_ns_; }
  // The time of the next read that returns bytes; kNever when nothing is pending.
  [[nodiscard]] TimestampNs next_read_ns() const noexcept;
  // Performs that read: the bytes that arrived by then. Valid until the next send or read.
  [[nodiscard]] std::span<const std::uint8_t> read(TimestampNs& stamp_ns);

  [[nodiscard]] std::uint64_t refused() const noexcept { return refused_.value(); }
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return buffer_.capacity(); }

  static constexpr TimestampNs kNever = INT64_MAX;

 private:
  // Arrival time of the byte at `index` in the buffer.
  [[nodiscard]] TimestampNs arrival_ns(std::size_t index) const noexcept;

  TimestampNs byte_ns_;
  TimestampNs read_interval_ns_;
  std::vector<std::uint8_t> buffer_;   // unread bytes first, then free room
  std::vector<TimestampNs> start_ns_;  // per unread byte: when its telegram started
  std::vector<std::uint32_t> index_;   // per unread byte: its index in its telegram
  std::size_t unread_ = 0;
  std::size_t returned_ = 0;  // bytes handed out by the last read, removed on the next call
  TimestampNs busy_until_ns_ = 0;
  MonotonicCounter refused_;
};

}  // namespace blockmap::hal::sim
