#include "outputs/output_thread.hpp"

#include <chrono>

#include "blockmap/core/check.hpp"

namespace blockmap::cli {
namespace {

// How long the output thread sleeps when there is nothing to write, and the pipeline thread
// when there is no room: short against the 1 s between plane updates.
constexpr auto kIdle = std::chrono::microseconds(500);

}  // namespace

OutputThread::OutputThread(MapOutputs& outputs, const OutputCapacity& capacity)
    : outputs_(outputs),
      event_slots_(capacity.events + 1),
      events_(event_slots_),
      changes_(capacity.changes),
      buildings_(capacity.buildings),
      poses_(capacity.poses) {
  changes_.batch.resize(capacity.changes);
  buildings_.batch.resize(capacity.buildings);
  poses_.batch.resize(capacity.poses);
}

OutputThread::~OutputThread() {
  finish();
}

void OutputThread::start() {
  thread_ = std::thread([this] { run(); });
}

void OutputThread::finish() {
  finishing_.store(true, std::memory_order_release);
  if (thread_.joinable()) {
    thread_.join();
  }
}

std::size_t OutputThread::memory_bytes() const noexcept {
  return events_.memory_bytes() + changes_.queue.memory_bytes() +
         changes_.batch.size() * sizeof(msg::PlaneChange) + buildings_.queue.memory_bytes() +
         buildings_.batch.size() * sizeof(buildings::Building) + poses_.queue.memory_bytes() +
         poses_.batch.size() * sizeof(localize::Pose3);
}

template <typename T>
void OutputThread::wait_for_room(const Lane<T>& lane, std::size_t count) {
  BLOCKMAP_CHECK_MSG(count <= lane.queue.capacity(),
                     "an output event larger than its queue (OutputCapacity)");
  bool waited = false;
  while (lane.queue.capacity() - lane.queue.size_approx() < count ||
         events_.capacity() == events_.size_approx()) {
    waited = true;
    std::this_thread::sleep_for(kIdle);
  }
  if (waited) {
    waits_.increment();
  }
}

template <typename T>
void OutputThread::put(Lane<T>& lane, Kind kind, TimestampNs stamp_ns, std::span<const T> items) {
  wait_for_room(lane, items.size());
  for (const T& item : items) {
    static_cast<void>(lane.queue.try_push(item));  // room was made for all of them
  }
  static_cast<void>(events_.try_push(Event{kind, stamp_ns, items.size()}));
}

void OutputThread::put_update(TimestampNs stamp_ns, std::span<const msg::PlaneChange> changes) {
  if (!changes.empty()) {
    put(changes_, Kind::kUpdate, stamp_ns, changes);
  }
}

void OutputThread::put_buildings(TimestampNs stamp_ns,
                                 std::span<const buildings::Building> buildings) {
  put(buildings_, Kind::kBuildings, stamp_ns, buildings);
}

void OutputThread::put_poses(std::span<const localize::Pose3> poses) {
  if (!poses.empty()) {
    put(poses_, Kind::kPoses, 0, poses);
  }
}

bool OutputThread::write_next() {
  Event event;
  if (!events_.try_pop(event)) {
    return false;
  }
  // An event's items were all queued before the event itself.
  const auto take = [&](auto& lane) {
    for (std::size_t i = 0; i < event.count; ++i) {
      static_cast<void>(lane.queue.try_pop(lane.batch[i]));
    }
    return std::span(lane.batch.data(), event.count);
  };
  switch (event.kind) {
    case Kind::kUpdate:
      outputs_.write_update(event.stamp_ns, take(changes_));
      break;
    case Kind::kBuildings:
      outputs_.write_buildings(event.stamp_ns, take(buildings_));
      break;
    case Kind::kPoses:
      outputs_.write_poses(take(poses_));
      break;
  }
  return true;
}

bool OutputThread::write_snapshot() {
  const std::size_t bytes = snapshot_bytes_.load(std::memory_order_acquire);
  if (bytes == 0 || snapshots_ == nullptr) {
    return false;
  }
  if (!snapshots_->write_encoded(bytes).empty()) {
    snapshot_failures_.increment();  // the last snapshot stays; health.jsonl shows it
  }
  snapshot_bytes_.store(0, std::memory_order_release);
  return true;
}

void OutputThread::run() {
  for (;;) {
    // Read before the queue: when finishing, everything put before it is in the queue.
    const bool finishing = finishing_.load(std::memory_order_acquire);
    const bool wrote_snapshot = write_snapshot();
    if (write_next() || wrote_snapshot) {
      continue;
    }
    if (finishing) {
      return;
    }
    std::this_thread::sleep_for(kIdle);
  }
}

}  // namespace blockmap::cli
