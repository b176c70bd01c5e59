#include "blockmap/hal/sim/scripted_byte_stream.hpp"

#include <algorithm>

#include "blockmap/core/check.hpp"
#include "blockmap/hal/sim/random.hpp"

namespace blockmap::hal::sim {
namespace {

std::size_t uniform_size(std::minstd_rand& random, std::size_t low, std::size_t high) {
  return low + static_cast<std::size_t>(uniform_unit(random) * static_cast<double>(high - low + 1));
}

}  // namespace

ScriptedByteStream::ScriptedByteStream(std::span<const std::uint8_t> script, ManualClock& clock,
                                       const ScriptedStreamConfig& config,
                                       std::span<std::uint8_t> written_storage)
    : script_(script),
      clock_(clock),
      config_(config),
      random_(config.seed),
      written_(written_storage),
      wire_start_ns_(clock.now_ns()) {
  BLOCKMAP_CHECK_MSG(config.max_chunk_bytes > 0, "scripted stream chunks need at least one byte");
}

void ScriptedByteStream::set_script(std::span<const std::uint8_t> script) noexcept {
  script_ = script;
  position_ = 0;
}

ReadResult ScriptedByteStream::do_read(std::span<std::uint8_t> buffer, TimestampNs /*timeout_ns*/) {
  if (finished()) {
    return ReadResult{IoStatus::kClosed, 0, 0};
  }
  std::size_t filled = 0;
  if (config_.garbage_probability > 0.0 && uniform_unit(random_) < config_.garbage_probability) {
    const std::size_t garbage = std::min(buffer.size() - 1, uniform_size(random_, 1, 16));
    for (std::size_t i = 0; i < garbage; ++i) {
      buffer[filled++] = static_cast<std::uint8_t>(random_());
    }
    garbage_.increment(garbage);
  }
  const std::size_t chunk = std::min({uniform_size(random_, 1, config_.max_chunk_bytes),
                                      buffer.size() - filled, script_.size() - position_});
  for (std::size_t i = 0; i < chunk; ++i) {
    std::uint8_t byte = script_[position_++];
    if (config_.drop_probability > 0.0 && uniform_unit(random_) < config_.drop_probability) {
      drops_.increment();
      continue;
    }
    if (config_.bit_flip_probability > 0.0 &&
        uniform_unit(random_) < config_.bit_flip_probability) {
      byte = static_cast<std::uint8_t>(byte ^ (1U << (random_() % 8)));
      flips_.increment();
    }
    buffer[filled++] = byte;
  }
  if (config_.baud > 0) {  // 8N1: ten bit times per byte on the wire, counted from the start
    wire_bytes_ += chunk;
    const TimestampNs wire_end_ns = wire_start_ns_ + static_cast<TimestampNs>(wire_bytes_) * 10 *
                                                         kNanosecondsPerSecond /
                                                         static_cast<TimestampNs>(config_.baud);
    if (wire_end_ns > clock_.now_ns()) {
      clock_.set_ns(wire_end_ns);
    }
  }
  return ReadResult{IoStatus::kOk, filled, clock_.now_ns()};
}

WriteResult ScriptedByteStream::do_write(std::span<const std::uint8_t> bytes,
                                         TimestampNs /*timeout_ns*/) {
  for (std::uint8_t byte : bytes) {
    written_.push_overwrite(byte);
  }
  return WriteResult{IoStatus::kOk, bytes.size()};
}

IoStatus ScriptedByteStream::do_set_baud(std::uint32_t baud) {
  config_.baud = baud;
  wire_start_ns_ = clock_.now_ns();
  wire_bytes_ = 0;
  return IoStatus::kOk;
}

}  // namespace blockmap::hal::sim
