// GpiodLine: one line of a Linux GPIO chip through libgpiod (Debian bookworm ships libgpiod 1.6,
// whose API is the chip/line one, not 2.x's request objects): the status LED as an output, a
// mapping-enable switch (or a GPS PPS input) with both edges reported.
//
// Levels are logical: with `active_low` the line is inverted by the kernel (a switch to ground
// with a pull-up reads active when closed). Edge times are the kernel's, taken when the
// interrupt fired, on CLOCK_MONOTONIC (the GPIO character device's v1 events are monotonic
// since Linux 5.7), the base of every other stamp. A line another program holds is refused at
// open with the holder's name, so that two daemons never fight over one LED.
#pragma once

#include <cstdint>
#include <string>

#include "blockmap/hal/gpio_line.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace blockmap::hal::linux_backend {

enum class GpioDirection : std::uint8_t { kOutput, kInputWithEdges };

class GpiodLine final : public GpioLine {
 public:
  GpiodLine() = default;
  ~GpiodLine() override;

  // Requests line `offset` of `chip` ("gpiochip0", "/dev/gpiochip0", its label or its number)
  // for `consumer`. An output starts at `initial_level`. Empty when it worked, otherwise one line
  // naming the chip and line and why. Closes a line already open first.
  [[nodiscard]] std::string open(const std::string& chip, std::uint32_t offset,
                                 GpioDirection direction, bool active_low,
                                 const std::string& consumer, bool initial_level = false);
  void close() noexcept;
  [[nodiscard]] bool is_open() const noexcept { return line_ != nullptr; }

 protected:
  IoStatus do_set(bool active) override;
  IoStatus do_get(bool& active) override;
  GpioEdge do_wait_edge(TimestampNs timeout_ns) override;

 private:
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  GpioDirection direction_ = GpioDirection::kOutput;
};

}  // namespace blockmap::hal::linux_backend
