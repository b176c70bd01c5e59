// SerialPort: a ByteStream on a Linux tty through termios, for the SICK LMS2xx (RS-232/RS-422
// at 9600-500000 baud) and NMEA GPS receivers (4800-115200 baud), and USB serial adapters
// (/dev/ttyUSB*, /dev/ttyACM*).
//
// Raw mode, 8N1, no flow control, no character translation: the lasers' telegrams are binary
// (a 0x11 or 0x0D in a range reading must arrive as it was sent). The descriptor is
// non-blocking, and reads and writes wait with poll() for at most the caller's timeout, so a
// reader thread never blocks past it. A device that goes away (a USB adapter unplugged, the
// other end of a pseudo-terminal closed) reads as kDeviceLost; the owner closes the port and
// opens it again when the device is back (the daemon's watchdog). Reads are stamped with
// CLOCK_MONOTONIC when the bytes were taken from the kernel.
#pragma once

#include <cstdint>
#include <string>

#include "blockmap/hal/byte_stream.hpp"

namespace blockmap::hal::linux_backend {

class SerialPort final : public ByteStream {
 public:
  SerialPort() = default;
  ~SerialPort() override;

  // Opens `path` at `baud` with exclusive access (TIOCEXCL: a second opener is refused). Empty
  // when it worked, otherwise one line naming the path and the reason. Closes a port already
  // open first.
  [[nodiscard]] std::string open(const std::string& path, std::uint32_t baud);
  void close() noexcept;
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }
  [[nodiscard]] const std::string& path() const noexcept { return path_; }
  [[nodiscard]] std::uint32_t baud() const noexcept { return baud_; }

  // Whether termios can run a line at this rate (the standard rates from 50 to 4,000,000,
  // among them the LMS2xx's 500,000).
  [[nodiscard]] static bool supported_baud(std::uint32_t baud) noexcept;

 protected:
  ReadResult do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) override;
  WriteResult do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) override;
  IoStatus do_set_baud(std::uint32_t baud) override;

 private:
  int fd_ = -1;
  std::string path_;
  std::uint32_t baud_ = 0;
};

}  // namespace blockmap::hal::linux_backend
