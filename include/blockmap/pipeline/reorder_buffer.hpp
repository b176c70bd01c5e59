// The mapper's first stage: the devices' odometry, fixes and poses put back in time order. A
// message waits until it is window_s older than the newest one in, so that messages from
// different devices that arrive in any interleaving within that window are released oldest
// first. Fixed capacity: when full, the oldest goes early.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/msg/odometry.hpp"

namespace blockmap::pipeline {

struct TimedMessage {
  enum class Kind : std::uint8_t { kBase, kFix, kPose };
  TimestampNs stamp_ns = 0;
  Kind kind = Kind::kBase;
  msg::OdometrySample odometry;
  msg::ImuSample imu;
  localize::GpsObservation fix;
  double up_m = 0.0;
  localize::Pose3 pose;
};

class ReorderBuffer {
 public:
  void init(Arena& arena, std::size_t capacity, double window_s) {
    pending_ = arena.allocate_array<TimedMessage>(capacity, "mapper.reorder");
    window_ns_ = ns_from_seconds(window_s);
  }
  [[nodiscard]] static std::size_t arena_bytes(std::size_t capacity) noexcept {
    return capacity * sizeof(TimedMessage);
  }

  enum class Outcome : std::uint8_t {
    kQueued,
    kLate,         // older than a message already released: dropped
    kForcedEarly,  // queued, and the buffer was full: its oldest was released early
  };
  // `release(message)` takes each message that leaves the buffer, in time order.
  template <typename Release>
  Outcome add(const TimedMessage& message, Release&& release) {
    if (released_any_ && message.stamp_ns < released_ns_) {
      return Outcome::kLate;
    }
    Outcome outcome = Outcome::kQueued;
    if (count_ == pending_.size()) {
      outcome = Outcome::kForcedEarly;
      release_at(0, release);
      std::move(pending_.begin() + 1, pending_.begin() + static_cast<std::ptrdiff_t>(count_),
                pending_.begin());
      --count_;
    }
    // Insertion from the back: messages arrive nearly in order.
    std::size_t at = count_;
    while (at > 0 && pending_[at - 1].stamp_ns > message.stamp_ns) {
      pending_[at] = pending_[at - 1];
      --at;
    }
    pending_[at] = message;
    ++count_;
    newest_in_ns_ = std::max(newest_in_ns_, message.stamp_ns);
    return outcome;
  }

  // Releases every message window_s older than the newest (all of them when `all`).
  template <typename Release>
  void release_due(bool all, Release&& release) {
    const TimestampNs due_ns = newest_in_ns_ - window_ns_;
    std::size_t released = 0;
    while (released < count_ && (all || pending_[released].stamp_ns <= due_ns)) {
      release_at(released, release);
      ++released;
    }
    if (released > 0) {
      std::move(pending_.begin() + static_cast<std::ptrdiff_t>(released),
                pending_.begin() + static_cast<std::ptrdiff_t>(count_), pending_.begin());
      count_ -= released;
    }
  }

  [[nodiscard]] std::size_t size() const noexcept { return count_; }

 private:
  template <typename Release>
  void release_at(std::size_t index, Release& release) {
    released_ns_ = pending_[index].stamp_ns;
    released_any_ = true;
    release(pending_[index]);
  }

  std::span<TimedMessage> pending_;  // ordered by time, oldest first
  std::size_t count_ = 0;
  TimestampNs window_ns_ = 0;
  TimestampNs newest_in_ns_ = 0;
  TimestampNs released_ns_ = 0;
  bool released_any_ = false;
};

}  // namespace blockmap::pipeline
