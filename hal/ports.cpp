// The non-virtual fronts of the ports: argument checks and traffic counters, once for every
// backend.
#include "blockmap/hal/byte_stream.hpp"
#include "blockmap/hal/can_bus.hpp"
#include "blockmap/hal/gpio_line.hpp"
#include "blockmap/hal/usb_bulk.hpp"

namespace blockmap::hal {
namespace {

// Would-block and time-outs are the normal rhythm of a poll loop, not failures.
bool is_failure(IoStatus status) noexcept {
  return status != IoStatus::kOk && status != IoStatus::kWouldBlock &&
         status != IoStatus::kTimedOut;
}

}  // namespace

ReadResult ByteStream::read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) {
  if (buffer.empty() || timeout_ns < 0) {
    return ReadResult{IoStatus::kInvalidArgument, 0, 0};
  }
  const ReadResult result = do_read(buffer, timeout_ns);
  bytes_read_.increment(result.bytes);
  if (is_failure(result.status)) {
    failures_.increment();
  }
  return result;
}

WriteResult ByteStream::write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) {
  if (timeout_ns < 0) {
    return WriteResult{IoStatus::kInvalidArgument, 0};
  }
  if (bytes.empty()) {
    return WriteResult{IoStatus::kOk, 0};
  }
  const WriteResult result = do_write(bytes, timeout_ns);
  bytes_written_.increment(result.bytes);
  if (is_failure(result.status)) {
    failures_.increment();
  }
  return result;
}

IoStatus ByteStream::set_baud(std::uint32_t baud) {
  if (baud == 0) {
    return IoStatus::kInvalidArgument;
  }
  return do_set_baud(baud);
}

CanReceiveResult CanBus::receive(CanFrame& frame, TimestampNs timeout_ns) {
  if (timeout_ns < 0) {
    return CanReceiveResult{IoStatus::kInvalidArgument, 0};
  }
  const CanReceiveResult result = do_receive(frame, timeout_ns);
  if (result.status == IoStatus::kOk) {
    received_.increment();
    if (frame.error) {
      error_frames_.increment();
    }
  } else if (is_failure(result.status)) {
    failures_.increment();
  }
  return result;
}

IoStatus CanBus::send(const CanFrame& frame) {
  if (frame.dlc > 8 || (!frame.extended && frame.id > 0x7FF) || frame.id > 0x1FFFFFFF) {
    return IoStatus::kInvalidArgument;
  }
  const IoStatus status = do_send(frame);
  if (status == IoStatus::kOk) {
    sent_.increment();
  } else if (is_failure(status)) {
    failures_.increment();
  }
  return status;
}

IoStatus CanBus::set_filters(std::span<const CanFilter> filters) {
  return do_set_filters(filters);
}

ReadResult UsbBulk::transfer_in(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) {
  if (buffer.empty() || timeout_ns < 0) {
    return ReadResult{IoStatus::kInvalidArgument, 0, 0};
  }
  const ReadResult result = do_transfer_in(buffer, timeout_ns);
  bytes_in_.increment(result.bytes);
  if (is_failure(result.status)) {
    failures_.increment();
  }
  return result;
}

WriteResult UsbBulk::transfer_out(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) {
  if (timeout_ns < 0) {
    return WriteResult{IoStatus::kInvalidArgument, 0};
  }
  const WriteResult result = do_transfer_out(bytes, timeout_ns);
  bytes_out_.increment(result.bytes);
  if (is_failure(result.status)) {
    failures_.increment();
  }
  return result;
}

IoStatus GpioLine::set(bool active) {
  const IoStatus status = do_set(active);
  if (is_failure(status)) {
    failures_.increment();
  }
  return status;
}

IoStatus GpioLine::get(bool& active) {
  const IoStatus status = do_get(active);
  if (is_failure(status)) {
    failures_.increment();
  }
  return status;
}

GpioEdge GpioLine::wait_edge(TimestampNs timeout_ns) {
  if (timeout_ns < 0) {
    return GpioEdge{IoStatus::kInvalidArgument, false, 0};
  }
  const GpioEdge edge = do_wait_edge(timeout_ns);
  if (edge.status == IoStatus::kOk) {
    edges_.increment();
  } else if (is_failure(edge.status)) {
    failures_.increment();
  }
  return edge;
}

}  // namespace blockmap::hal
