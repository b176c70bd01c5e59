#include "blockmap/hal/linux/gpiod_line.hpp"

#include <gpiod.h>

#include <cerrno>
#include <ctime>

#include "descriptor_wait.hpp"

namespace blockmap::hal::linux_backend {
namespace {

// Errors after which the chip is gone (its driver unbound) rather than the call misused.
bool chip_gone(int error) noexcept {
  return error == ENODEV || error == ENXIO || error == EBADF || error == EIO;
}

IoStatus status_of_errno(int error) noexcept {
  return chip_gone(error) ? IoStatus::kDeviceLost : IoStatus::kIoError;
}

std::string line_name(const std::string& chip, std::uint32_t offset) {
  return chip + " line " + std::to_string(offset);
}

}  // namespace

GpiodLine::~GpiodLine() {
  close();
}

std::string GpiodLine::open(const std::string& chip, std::uint32_t offset, GpioDirection direction,
                            bool active_low, const std::string& consumer, bool initial_level) {
  close();
  chip_ = ::gpiod_chip_open_lookup(chip.c_str());
  if (chip_ == nullptr) {
    const int error = errno;
    return chip + ": cannot open the GPIO chip (" + error_text(error) + ")";
  }
  gpiod_line* line = ::gpiod_chip_get_line(chip_, offset);
  if (line == nullptr) {
    const int error = errno;
    const unsigned lines = ::gpiod_chip_num_lines(chip_);
    close();
    return line_name(chip, offset) + ": no such line (the chip has " + std::to_string(lines) +
           "; " + error_text(error) + ")";
  }
  if (::gpiod_line_is_used(line)) {
    const char* holder = ::gpiod_line_consumer(line);
    close();
    return line_name(chip, offset) + ": in use by " +
           (holder != nullptr ? std::string("\"") + holder + "\"" : std::string("the kernel"));
  }
  const int flags = active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  const int result =
      direction == GpioDirection::kOutput
          ? ::gpiod_line_request_output_flags(line, consumer.c_str(), flags, initial_level ? 1 : 0)
          : ::gpiod_line_request_both_edges_events_flags(line, consumer.c_str(), flags);
  if (result != 0) {
    const int error = errno;
    close();
    return line_name(chip, offset) + ": cannot request it as " +
           (direction == GpioDirection::kOutput ? "an output" : "an input with edge events") +
           " (" + error_text(error) + ")";
  }
  line_ = line;
  direction_ = direction;
  return {};
}

void GpiodLine::close() noexcept {
  if (line_ != nullptr) {
    ::gpiod_line_release(line_);
    line_ = nullptr;
  }
  if (chip_ != nullptr) {
    ::gpiod_chip_close(chip_);
    chip_ = nullptr;
  }
}

IoStatus GpiodLine::do_set(bool active) {
  if (line_ == nullptr) {
    return IoStatus::kClosed;
  }
  if (direction_ != GpioDirection::kOutput) {
    return IoStatus::kInvalidArgument;
  }
  if (::gpiod_line_set_value(line_, active ? 1 : 0) != 0) {
    return status_of_errno(errno);
  }
  return IoStatus::kOk;
}

IoStatus GpiodLine::do_get(bool& active) {
  if (line_ == nullptr) {
    return IoStatus::kClosed;
  }
  const int value = ::gpiod_line_get_value(line_);
  if (value < 0) {
    return status_of_errno(errno);
  }
  active = value == 1;
  return IoStatus::kOk;
}

GpioEdge GpiodLine::do_wait_edge(TimestampNs timeout_ns) {
  if (line_ == nullptr) {
    return GpioEdge{IoStatus::kClosed, false, 0};
  }
  if (direction_ != GpioDirection::kInputWithEdges) {
    return GpioEdge{IoStatus::kInvalidArgument, false, 0};
  }
  timespec timeout{};
  timeout.tv_sec = static_cast<std::time_t>(timeout_ns / kNanosecondsPerSecond);
  timeout.tv_nsec = static_cast<long>(timeout_ns % kNanosecondsPerSecond);
  const int waited = ::gpiod_line_event_wait(line_, &timeout);
  if (waited == 0) {
    return GpioEdge{IoStatus::kTimedOut, false, 0};
  }
  gpiod_line_event event{};
  if (waited < 0 || ::gpiod_line_event_read(line_, &event) != 0) {
    return GpioEdge{status_of_errno(errno), false, 0};
  }
  const TimestampNs stamp_ns = static_cast<TimestampNs>(event.ts.tv_sec) * kNanosecondsPerSecond +
                               static_cast<TimestampNs>(event.ts.tv_nsec);
  return GpioEdge{IoStatus::kOk, event.event_type == GPIOD_LINE_EVENT_RISING_EDGE, stamp_ns};
}

}  // namespace blockmap::hal::linux_backend
