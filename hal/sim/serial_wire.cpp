#include "blockmap/hal/sim/serial_wire.hpp"

#include <algorithm>

#include "blockmap/core/check.hpp"

namespace blockmap::hal::sim {

SerialWire::SerialWire(std::uint32_t baud, TimestampNs read_interval_ns, std::size_t capacity_bytes)
    : byte_ns_(static_cast<TimestampNs>(10'000'000'000LL / baud)),
      read_interval_ns_(read_interval_ns),
      buffer_(capacity_bytes),
      start_ns_(capacity_bytes),
      index_(capacity_bytes) {
  BLOCKMAP_CHECK_MSG(baud > 0 && read_interval_ns > 0 && capacity_bytes > 0, "bad serial wire");
}

TimestampNs SerialWire::arrival_ns(std::size_t index) const noexcept {
  return start_ns_[index] + static_cast<TimestampNs>(index_[index] + 1) * byte_ns_;
}

bool SerialWire::send(std::span<const std::uint8_t> bytes, TimestampNs earliest_ns) {
  // Drop what the last read handed out before adding more.
  if (returned_ > 0) {
    const std::size_t keep = unread_ - returned_;
    std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(returned_), keep, buffer_.begin());
    std::copy_n(start_ns_.begin() + static_cast<std::ptrdiff_t>(returned_), keep,
                start_ns_.begin());
    std::copy_n(index_.begin() + static_cast<std::ptrdiff_t>(returned_), keep, index_.begin());
    unread_ = keep;
    returned_ = 0;
  }
  if (bytes.size() > buffer_.size() - unread_) {
    refused_.increment();
    return false;
  }
  const TimestampNs start = std::max(earliest_ns, busy_until_ns_);
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    buffer_[unread_ + i] = bytes[i];
    start_ns_[unread_ + i] = start;
    index_[unread_ + i] = static_cast<std::uint32_t>(i);
  }
  unread_ += bytes.size();
  busy_until_ns_ = start + static_cast<TimestampNs>(bytes.size()) * byte_ns_;
  return true;
}

TimestampNs SerialWire::next_read_ns() const noexcept {
  if (unread_ == returned_) {
    return kNever;
  }
  // The first read at or after the next byte's arrival, on the host's read grid.
  const TimestampNs arrival = arrival_ns(returned_);
  return (arrival + read_interval_ns_ - 1) / read_interval_ns_ * read_interval_ns_;
}

std::span<const std::uint8_t> SerialWire::read(TimestampNs& stamp_ns) {
  stamp_ns = next_read_ns();
  if (stamp_ns == kNever) {
    return {};
  }
  const std::size_t first = returned_;
  std::size_t end = first;
  while (end < unread_ && arrival_ns(end) <= stamp_ns) {
    ++end;
  }
  // Move the consumed prefix out lazily: mark these bytes returned.
  const std::span<const std::uint8_t> bytes(buffer_.data() + first, end - first);
  returned_ = end;
  return bytes;
}

}  // namespace blockmap::hal::sim
