// ByteStream port: a serial line (termios), a USB CDC-ACM device (Hokuyo) or a simulated one.
//
// A non-virtual front checks arguments and counts traffic in one place; backends implement the
// protected do_* functions. Reads are stamped with the monotonic time the bytes were taken
// from the device, which is what the codecs stamp messages with.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/status.hpp"
#include "blockmap/core/time.hpp"

namespace blockmap::hal {

struct ReadResult {
  IoStatus status = IoStatus::kWouldBlock;
  std::size_t bytes = 0;     // bytes placed at the front of the caller's buffer
  TimestampNs stamp_ns = 0;  // when they were read (kOk only)
};

struct WriteResult {
  IoStatus status = IoStatus::kWouldBlock;
  std::size_t bytes = 0;  // bytes accepted (a short write is kOk with fewer bytes)
};

class ByteStream {
 public:
  ByteStream() = default;
  ByteStream(const ByteStream&) = delete;
  ByteStream& operator=(const ByteStream&) = delete;
  virtual ~ByteStream() = default;

  // Reads what is available, waiting at most timeout_ns (0: do not wait). Blocks the calling
  // thread (a device reader thread) for at most that long.
  ReadResult read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns);
  // Writes as much of `bytes` as the device takes within timeout_ns.
  WriteResult write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns);
  // Changes the line rate (serial ports); other streams answer kInvalidArgument.
  IoStatus set_baud(std::uint32_t baud);

  [[nodiscard]] std::uint64_t bytes_read() const noexcept { return bytes_read_.value(); }
  [[nodiscard]] std::uint64_t bytes_written() const noexcept { return bytes_written_.value(); }
  [[nodiscard]] std::uint64_t failures() const noexcept { return failures_.value(); }

 protected:
  virtual ReadResult do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) = 0;
  virtual WriteResult do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) = 0;
  virtual IoStatus do_set_baud(std::uint32_t /*baud*/) { return IoStatus::kInvalidArgument; }

 private:
  MonotonicCounter bytes_read_;
  MonotonicCounter bytes_written_;
  MonotonicCounter failures_;  // results other than ok, would-block and timed-out
};

}  // namespace blockmap::hal
