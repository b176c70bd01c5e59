// Scans waiting for their poses: each stays in a slot of its own (compacted, two bytes a beam)
// until the poses cover its last beam, and the queue is the list of the slots in arrival order.
// Fixed capacity, set at init.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/msg/laser_scan.hpp"
#include "blockmap/pipeline/compact_scan.hpp"

namespace blockmap::pipeline {

class ScanQueue {
 public:
  void init(Arena& arena, std::size_t slots, std::size_t max_beams);
  [[nodiscard]] static std::size_t arena_bytes(std::size_t slots, std::size_t max_beams) noexcept;

  enum class Outcome : std::uint8_t { kQueued, kFull, kTooManyBeams };
  Outcome push(std::size_t laser, const msg::LaserScan& scan) noexcept;

  // The oldest queued scan whose last beam the poses cover (every one when `ending`), or -1.
  // oldest_waiting_ns: the oldest stamp among the scans they do not cover yet. Messages arrive
  // within reorder_window_ns of time order, so no scan past the horizon by more is looked at.
  [[nodiscard]] std::ptrdiff_t next_ready(bool have_poses, TimestampNs horizon_ns,
                                          TimestampNs reorder_window_ns, bool ending,
                                          TimestampNs& oldest_waiting_ns) const noexcept;
  [[nodiscard]] std::size_t laser(std::size_t position) const noexcept;
  [[nodiscard]] const CompactScanHeader& header(std::size_t position) const noexcept;
  // The scan at `position` in full; valid until the next call.
  [[nodiscard]] const msg::LaserScan& expand(std::size_t position) noexcept;
  // Takes the scan at `position` out (its slot becomes free); the others keep their order.
  void remove(std::size_t position) noexcept;
  // Takes out every scan that starts before `bound_ns`; how many.
  std::size_t remove_before(TimestampNs bound_ns) noexcept;

  [[nodiscard]] std::size_t size() const noexcept { return count_; }
  // The oldest stamp queued; the largest stamp when empty.
  [[nodiscard]] TimestampNs oldest_stamp() const noexcept;

 private:
  struct QueuedScan {
    std::size_t laser = 0;
    CompactScanHeader scan;  // its beams: codes_, max_beams_ per slot
  };
  [[nodiscard]] std::span<std::uint16_t> codes_of(std::uint32_t slot) const noexcept {
    return codes_.subspan(slot * max_beams_, max_beams_);
  }

  std::span<QueuedScan> scans_;
  std::span<std::uint32_t> slots_;  // [0, count_): waiting, in arrival order; the rest free
  std::span<std::uint16_t> codes_;
  msg::LaserScan* expanded_ = nullptr;
  std::size_t max_beams_ = 0;
  std::size_t count_ = 0;
};

}  // namespace blockmap::pipeline
