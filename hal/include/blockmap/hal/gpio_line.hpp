// GpioLine port: one line of a GPIO chip (libgpiod on the robot): a status LED output, or an
// input such as a mapping-enable switch or GPS PPS, with edge events.
#pragma once

#include <cstdint>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/status.hpp"
#include "blockmap/core/time.hpp"

namespace blockmap::hal {

struct GpioEdge {
  IoStatus status = IoStatus::kWouldBlock;
  bool rising = false;
  TimestampNs stamp_ns = 0;  // the kernel's event time
};

class GpioLine {
 public:
  GpioLine() = default;
  GpioLine(const GpioLine&) = delete;
  GpioLine& operator=(const GpioLine&) = delete;
  virtual ~GpioLine() = default;

  IoStatus set(bool active);  // outputs only
  IoStatus get(bool& active);
  GpioEdge wait_edge(TimestampNs timeout_ns);  // inputs requested with edge detection

  [[nodiscard]] std::uint64_t edges() const noexcept { return edges_.value(); }
  [[nodiscard]] std::uint64_t failures() const noexcept { return failures_.value(); }

 protected:
  virtual IoStatus do_set(bool active) = 0;
  virtual IoStatus do_get(bool& active) = 0;
  virtual GpioEdge do_wait_edge(TimestampNs timeout_ns) = 0;

 private:
  MonotonicCounter edges_;
  MonotonicCounter failures_;
};

}  // namespace blockmap::hal
