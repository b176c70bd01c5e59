// OutputThread: the daemon's outputs written off the pipeline thread. Writing a
// plane update means formatting JSON (which allocates) and file and socket I/O (which may
// stall on a robot's SD card); the pipeline thread does neither. It copies each update's
// changes, the buildings and the smoothed poses into queues whose room is taken at start-up,
// and this thread hands them to MapOutputs in the order they were put.
//
// When a queue has no room (the disk stalled longer than the queues hold), the pipeline thread
// waits for it rather than drop an update: the wait is counted, and the device queues behind
// the pipeline absorb it (their refusals are counted in health.jsonl).
#pragma once

#include <atomic>
#include <cstdint>
#include <span>
#include <thread>
#include <vector>

#include "blockmap/buildings/building.hpp"
#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/plane_patch.hpp"
#include "daemon/snapshot.hpp"
#include "outputs/map_outputs.hpp"

namespace blockmap::cli {

struct OutputCapacity {
  std::size_t changes = 4096;  // plane changes waiting (at least one update's most)
  std::size_t buildings = 128;
  std::size_t poses = 1024;
  std::size_t events = 256;  // updates, building lists and pose batches waiting
};

class OutputThread {
 public:
  OutputThread(MapOutputs& outputs, const OutputCapacity& capacity);
  ~OutputThread();
  OutputThread(const OutputThread&) = delete;
  OutputThread& operator=(const OutputThread&) = delete;

  void start();
  // Writes everything put so far, then ends the thread.
  void finish();

  // The pipeline thread's side: each waits for room when the queues are full. None allocates.
  void put_update(TimestampNs stamp_ns, std::span<const msg::PlaneChange> changes);
  void put_buildings(TimestampNs stamp_ns, std::span<const buildings::Building> buildings);
  void put_poses(std::span<const localize::Pose3> poses);

  // Snapshots: the pipeline encodes one into `writer` (daemon/snapshot.hpp) while none is
  // pending, then hands its size over; this thread writes it (write, fsync, rename) and frees
  // the writer again. A snapshot due while the last is still being written is skipped.
  void set_snapshots(daemon::SnapshotWriter* writer) noexcept { snapshots_ = writer; }
  [[nodiscard]] bool snapshot_pending() const noexcept {
    return snapshot_bytes_.load(std::memory_order_acquire) != 0;
  }
  void put_snapshot(std::size_t bytes) noexcept {
    snapshot_bytes_.store(bytes, std::memory_order_release);
  }
  [[nodiscard]] std::uint64_t snapshot_failures() const noexcept {
    return snapshot_failures_.value();
  }

  [[nodiscard]] std::uint64_t waits() const noexcept { return waits_.value(); }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  enum class Kind : std::uint8_t { kUpdate, kBuildings, kPoses };
  struct Event {
    Kind kind = Kind::kUpdate;
    TimestampNs stamp_ns = 0;
    std::size_t count = 0;
  };
  template <typename T>
  struct Lane {
    explicit Lane(std::size_t capacity) : slots(capacity + 1), queue(slots) {}
    std::vector<T> slots;
    SpscQueueRef<T> queue;
    std::vector<T> batch;  // the output thread's copy of one event's items
  };

  // Waits until `lane` has room for `count` more and the event queue for one more.
  template <typename T>
  void wait_for_room(const Lane<T>& lane, std::size_t count);
  template <typename T>
  void put(Lane<T>& lane, Kind kind, TimestampNs stamp_ns, std::span<const T> items);
  void run();
  // Writes the next event; false when there was none.
  bool write_next();
  // Writes the pending snapshot; false when there was none.
  bool write_snapshot();

  MapOutputs& outputs_;
  std::vector<Event> event_slots_;
  SpscQueueRef<Event> events_;
  Lane<msg::PlaneChange> changes_;
  Lane<buildings::Building> buildings_;
  Lane<localize::Pose3> poses_;
  daemon::SnapshotWriter* snapshots_ = nullptr;
  std::atomic<std::size_t> snapshot_bytes_{0};
  MonotonicCounter snapshot_failures_;
  std::atomic<bool> finishing_{false};
  std::thread thread_;
  MonotonicCounter waits_;
};

}  // namespace blockmap::cli
