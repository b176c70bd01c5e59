// ScriptedByteStream: a simulated serial line that replays a capture (or the bytes a simulated
// device produced) in chunks of random size, optionally damaging it the ways a cable does, and
// records what the host writes. Deterministic for a given seed; time comes from a ManualClock.
// Single-threaded: the simulation drives it.
#pragma once

#include <cstdint>
#include <random>
#include <span>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/hal/byte_stream.hpp"
#include "blockmap/hal/sim/manual_clock.hpp"

namespace blockmap::hal::sim {

struct ScriptedStreamConfig {
  std::uint32_t seed = 1;
  std::size_t max_chunk_bytes = 64;   // each read returns 1..max_chunk_bytes bytes
  std::uint32_t baud = 0;             // > 0: each byte takes 10 bit times of simulated time
  double bit_flip_probability = 0.0;  // per byte: one random bit flipped
  double drop_probability = 0.0;      // per byte: the byte is lost
  double garbage_probability = 0.0;   // per read: 1..16 random bytes inserted before the chunk
};

class ScriptedByteStream final : public ByteStream {
 public:
  // `script` and `written_storage` must outlive the stream; the host's writes beyond
  // written_storage's capacity drop the oldest (counted).
  ScriptedByteStream(std::span<const std::uint8_t> script, ManualClock& clock,
                     const ScriptedStreamConfig& config, std::span<std::uint8_t> written_storage);

  // Replaces the bytes still to be delivered (a simulated device's next reply).
  void set_script(std::span<const std::uint8_t> script) noexcept;
  [[nodiscard]] bool finished() const noexcept { return position_ == script_.size(); }
  // What the host wrote, oldest first.
  [[nodiscard]] const RingBufferRef<std::uint8_t>& written() const noexcept { return written_; }

  [[nodiscard]] std::uint64_t injected_bit_flips() const noexcept { return flips_.value(); }
  [[nodiscard]] std::uint64_t injected_drops() const noexcept { return drops_.value(); }
  [[nodiscard]] std::uint64_t injected_garbage_bytes() const noexcept { return garbage_.value(); }

 protected:
  ReadResult do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;
  IoStatus do_set_baud(std::uint32_t baud) override;

 private:
  std::span<const std::uint8_t> script_;
  std::size_t position_ = 0;
  ManualClock& clock_;
  ScriptedStreamConfig config_;
  std::minstd_rand random_;
  RingBufferRef<std::uint8_t> written_;
  TimestampNs wire_start_ns_ = 0;  // line time: bytes since then at the current baud
  std::uint64_t wire_bytes_ = 0;
  MonotonicCounter flips_;
  MonotonicCounter drops_;
  MonotonicCounter garbage_;
};

}  // namespace blockmap::hal::sim
