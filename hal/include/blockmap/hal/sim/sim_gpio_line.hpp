// SimGpioLine: a GPIO line whose input level the simulation drives (edges are queued with
// their time) and whose output level tests can read back. Single-threaded.
#pragma once

#include <span>

#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/hal/gpio_line.hpp"

namespace blockmap::hal::sim {

class SimGpioLine final : public GpioLine {
 public:
  // `edge_storage` queues edges not yet waited for (oldest dropped when full, counted).
  explicit SimGpioLine(std::span<GpioEdge> edge_storage) : pending_edges_(edge_storage) {}

  // The outside world sets the input to `level` at `stamp_ns`; a change queues an edge.
  void drive(bool level, TimestampNs stamp_ns);
  [[nodiscard]] bool level() const noexcept { return level_; }
  [[nodiscard]] const RingBufferRef<GpioEdge>& pending_edges() const noexcept {
    return pending_edges_;
  }

 protected:
  IoStatus do_set(bool active) override;
  IoStatus do_get(bool& active) override;
  GpioEdge do_wait_edge(TimestampNs timeout_ns) override;

 private:
  bool level_ = false;
  RingBufferRef<GpioEdge> pending_edges_;
};

}  // namespace blockmap::hal::sim
