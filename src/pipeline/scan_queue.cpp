#include "blockmap/pipeline/scan_queue.hpp"

#include <algorithm>
#include <limits>

namespace blockmap::pipeline {

void ScanQueue::init(Arena& arena, std::size_t slots, std::size_t max_beams) {
  max_beams_ = max_beams;
  scans_ = arena.allocate_array<QueuedScan>(slots, "mapper.scans");
  slots_ = arena.allocate_array<std::uint32_t>(slots, "mapper.scans");
  codes_ = arena.allocate_array<std::uint16_t>(slots * max_beams, "mapper.scans");
  expanded_ = arena.allocate_array<msg::LaserScan>(1, "mapper.scans").data();
  for (std::size_t slot = 0; slot < slots_.size(); ++slot) {
    slots_[slot] = static_cast<std::uint32_t>(slot);
  }
}

std::size_t ScanQueue::arena_bytes(std::size_t slots, std::size_t max_beams) noexcept {
  return slots * (sizeof(QueuedScan) + sizeof(std::uint32_t) + max_beams * sizeof(std::uint16_t)) +
         sizeof(msg::LaserScan);
}

ScanQueue::Outcome ScanQueue::push(std::size_t laser, const msg::LaserScan& scan) noexcept {
  if (count_ == scans_.size()) {
    return Outcome::kFull;
  }
  // The slots past the queue's end are the free ones.
  const std::uint32_t slot = slots_[count_];
  QueuedScan& queued = scans_[slot];
  if (!compact_scan(scan, queued.scan, codes_of(slot))) {
    return Outcome::kTooManyBeams;
  }
  queued.laser = laser;
  ++count_;
  return Outcome::kQueued;
}

std::ptrdiff_t ScanQueue::next_ready(bool have_poses, TimestampNs horizon_ns,
                                     TimestampNs reorder_window_ns, bool ending,
                                     TimestampNs& oldest_waiting_ns) const noexcept {
  std::ptrdiff_t oldest = -1;
  TimestampNs oldest_ns = 0;
  oldest_waiting_ns = std::numeric_limits<TimestampNs>::max();
  // The queue is in arrival order: past a scan that much newer than the horizon, none is
  // covered, and none older than the horizon waits. (With a pose lag the queue holds
  // thousands of scans.)
  const TimestampNs last_useful_ns = horizon_ns + reorder_window_ns;
  for (std::size_t i = 0; i < count_; ++i) {
    const CompactScanHeader& scan = scans_[slots_[i]].scan;
    if (have_poses && !ending && scan.header.stamp_ns > last_useful_ns) {
      break;
    }
    const bool covered = have_poses && scan.last_beam_ns <= horizon_ns;
    if (!covered) {
      oldest_waiting_ns = std::min(oldest_waiting_ns, scan.header.stamp_ns);
    }
    if ((covered || ending) && (oldest < 0 || scan.header.stamp_ns < oldest_ns)) {
      oldest = static_cast<std::ptrdiff_t>(i);
      oldest_ns = scan.header.stamp_ns;
    }
  }
  return oldest;
}

std::size_t ScanQueue::laser(std::size_t position) const noexcept {
  return scans_[slots_[position]].laser;
}

const CompactScanHeader& ScanQueue::header(std::size_t position) const noexcept {
  return scans_[slots_[position]].scan;
}

const msg::LaserScan& ScanQueue::expand(std::size_t position) noexcept {
  const std::uint32_t slot = slots_[position];
  expand_scan(scans_[slot].scan, codes_of(slot), *expanded_);
  return *expanded_;
}

void ScanQueue::remove(std::size_t position) noexcept {
  // The queue's order is kept (equal stamps go in arrival order), and the slot joins the
  // free ones after the queue's end.
  const std::uint32_t slot = slots_[position];
  for (std::size_t i = position; i + 1 < count_; ++i) {
    slots_[i] = slots_[i + 1];
  }
  --count_;
  slots_[count_] = slot;
}

std::size_t ScanQueue::remove_before(TimestampNs bound_ns) noexcept {
  std::size_t removed = 0;
  for (std::size_t i = 0; i < count_;) {
    if (scans_[slots_[i]].scan.header.stamp_ns < bound_ns) {
      remove(i);
      ++removed;
    } else {
      ++i;
    }
  }
  return removed;
}

TimestampNs ScanQueue::oldest_stamp() const noexcept {
  TimestampNs oldest_ns = std::numeric_limits<TimestampNs>::max();
  for (std::size_t i = 0; i < count_; ++i) {
    oldest_ns = std::min(oldest_ns, scans_[slots_[i]].scan.header.stamp_ns);
  }
  return oldest_ns;
}

}  // namespace blockmap::pipeline
