#include "blockmap/hal/sim/sim_gpio_line.hpp"

namespace blockmap::hal::sim {

void SimGpioLine::drive(bool level, TimestampNs stamp_ns) {
  if (level != level_) {
    pending_edges_.push_overwrite(GpioEdge{IoStatus::kOk, level, stamp_ns});
  }
  level_ = level;
}

IoStatus SimGpioLine::do_set(bool active) {
  level_ = active;
  return IoStatus::kOk;
}

IoStatus SimGpioLine::do_get(bool& active) {
  active = level_;
  return IoStatus::kOk;
}

GpioEdge SimGpioLine::do_wait_edge(TimestampNs /*timeout_ns*/) {
  GpioEdge edge;
  if (!pending_edges_.try_pop(edge)) {
    return GpioEdge{IoStatus::kWouldBlock, false, 0};
  }
  return edge;
}

}  // namespace blockmap::hal::sim
