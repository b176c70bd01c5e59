#include "blockmap/hal/sim/sim_ports.hpp"

#include <algorithm>

#include "blockmap/core/check.hpp"

namespace blockmap::hal::sim {

SimSerialPort::SimSerialPort(std::size_t capacity_bytes, std::size_t capacity_chunks)
    : storage_(capacity_bytes),
      chunk_storage_(capacity_chunks),
      bytes_(storage_),
      chunks_(chunk_storage_) {}

bool SimSerialPort::deliver(std::span<const std::uint8_t> bytes, TimestampNs stamp_ns) {
  if (bytes.empty()) {
    return true;
  }
  if (bytes.size() > bytes_.capacity() - bytes_.size() || chunks_.full()) {
    overflows_.increment();
    return false;
  }
  for (const std::uint8_t byte : bytes) {
    (void)bytes_.try_push(byte);
  }
  (void)chunks_.try_push({stamp_ns, bytes.size()});
  return true;
}

ReadResult SimSerialPort::do_read(std::span<std::uint8_t> buffer, TimestampNs /*timeout_ns*/) {
  if (chunks_.empty()) {
    return {IoStatus::kWouldBlock, 0, 0};
  }
  ChunkRecord& chunk = chunks_.front();
  const std::size_t count = std::min(chunk.length, buffer.size());
  for (std::size_t i = 0; i < count; ++i) {
    buffer[i] = bytes_.front();
    bytes_.pop_front();
  }
  const TimestampNs stamp = chunk.stamp_ns;
  chunk.length -= count;
  if (chunk.length == 0) {
    chunks_.pop_front();
  }
  return {IoStatus::kOk, count, stamp};
}

WriteResult SimSerialPort::do_write(std::span<const std::uint8_t> bytes,
                                    TimestampNs /*timeout_ns*/) {
  for (const std::uint8_t byte : bytes) {
    written_.push_overwrite(byte);
  }
  return {IoStatus::kOk, bytes.size()};
}

SimPorts::SimPorts(ManualClock& clock, LoopbackCanBus& can, std::span<SimSerialPort* const> serial)
    : clock_(clock), can_(can), serial_(serial) {}

void SimPorts::move_clock_to(TimestampNs stamp_ns) {
  if (stamp_ns > clock_.now_ns()) {
    clock_.set_ns(stamp_ns);
  }
}

void SimPorts::on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) {
  move_clock_to(stamp_ns);
  if (can_.inject(frame) != IoStatus::kOk) {
    can_overflows_.increment();
  }
}

void SimPorts::on_serial(std::size_t device, TimestampNs stamp_ns,
                         protocol::byte_log::Direction direction,
                         std::span<const std::uint8_t> bytes) {
  BLOCKMAP_CHECK_MSG(device < serial_.size(), "a serial device without a port");
  move_clock_to(stamp_ns);
  if (direction == protocol::byte_log::Direction::kFromDevice) {
    (void)serial_[device]->deliver(bytes, stamp_ns);
  }
}

}  // namespace blockmap::hal::sim
