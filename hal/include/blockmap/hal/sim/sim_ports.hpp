// The simulated robot's devices on the ports the real ones use: a Simulation's CAN frames go onto
// a LoopbackCanBus and its serial bytes into SimSerialPorts, with the ManualClock moved to each
// one's time, so that SegwayBase, Lms2xxScanner and GpsReceiver (and `blockmap run`) read and
// decode the same bytes, timed the same way, as on the robot.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/hal/byte_stream.hpp"
#include "blockmap/hal/sim/loopback_can_bus.hpp"
#include "blockmap/hal/sim/manual_clock.hpp"
#include "blockmap/hal/sim/simulation.hpp"

namespace blockmap::hal::sim {

// A serial port whose bytes a simulation delivers: each read returns the oldest delivered chunk
// (or as much of it as the caller's buffer holds), stamped with the time it arrived.
class SimSerialPort final : public ByteStream {
 public:
  explicit SimSerialPort(std::size_t capacity_bytes = 8192, std::size_t capacity_chunks = 256);

  // False, and counted, when the port's buffer is full (the host stopped reading).
  bool deliver(std::span<const std::uint8_t> bytes, TimestampNs stamp_ns);
  [[nodiscard]] std::size_t pending_bytes() const noexcept { return bytes_.size(); }
  // What the host wrote (the newest 256 bytes).
  [[nodiscard]] const RingBufferRef<std::uint8_t>& written() const noexcept { return written_; }
  [[nodiscard]] std::uint64_t overflows() const noexcept { return overflows_.value(); }

 protected:
  ReadResult do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;
  IoStatus do_set_baud(std::uint32_t /*baud*/) override { return IoStatus::kOk; }

 private:
  struct ChunkRecord {
    TimestampNs stamp_ns = 0;
    std::size_t length = 0;
  };
  std::vector<std::uint8_t> storage_;
  std::vector<ChunkRecord> chunk_storage_;
  RingBufferRef<std::uint8_t> bytes_;
  RingBufferRef<ChunkRecord> chunks_;
  RingBuffer<std::uint8_t, 256> written_;
  MonotonicCounter overflows_;
};

// Routes a simulation's output onto the ports. `serial` holds one port per serial device of the
// simulation (lasers, then the GPS); the ports must outlive this object.
class SimPorts final : public SimSink {
 public:
  SimPorts(ManualClock& clock, LoopbackCanBus& can, std::span<SimSerialPort* const> serial);

  void on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) override;
  void on_serial(std::size_t device, TimestampNs stamp_ns, protocol::byte_log::Direction direction,
                 std::span<const std::uint8_t> bytes) override;

  [[nodiscard]] std::uint64_t can_overflows() const noexcept { return can_overflows_.value(); }

 private:
  void move_clock_to(TimestampNs stamp_ns);

  ManualClock& clock_;
  LoopbackCanBus& can_;
  std::span<SimSerialPort* const> serial_;
  MonotonicCounter can_overflows_;
};

}  // namespace blockmap::hal::sim
