#include "blockmap/hal/linux/serial_port.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <ctime>
#include <utility>

#include "descriptor_wait.hpp"

namespace blockmap::hal::linux_backend {
namespace {

// termios speeds are symbols, not numbers.
constexpr std::array<std::pair<std::uint32_t, speed_t>, 30> kSpeeds{{
    {50, B50},           {75, B75},           {110, B110},         {134, B134},
    {150, B150},         {200, B200},         {300, B300},         {600, B600},
    {1200, B1200},       {1800, B1800},       {2400, B2400},       {4800, B4800},
    {9600, B9600},       {19200, B19200},     {38400, B38400},     {57600, B57600},
    {115200, B115200},   {230400, B230400},   {460800, B460800},   {500000, B500000},
    {576000, B576000},   {921600, B921600},   {1000000, B1000000}, {1152000, B1152000},
    {1500000, B1500000}, {2000000, B2000000}, {2500000, B2500000}, {3000000, B3000000},
    {3500000, B3500000}, {4000000, B4000000},
}};

bool speed_of(std::uint32_t baud, speed_t& speed) noexcept {
  for (const auto& [rate, symbol] : kSpeeds) {
    if (rate == baud) {
      speed = symbol;
      return true;
    }
  }
  return false;
}

// Errors that mean the device is gone rather than misused.
bool device_gone(int error) noexcept {
  return error == EIO || error == ENXIO || error == ENODEV || error == EBADF;
}

// Raw 8N1 at `speed`, no flow control, reads return what is there (VMIN 0, VTIME 0).
bool configure_raw(int fd, speed_t speed, int& error) noexcept {
  termios settings{};
  if (::tcgetattr(fd, &settings) != 0) {
    error = errno;
    return false;
  }
  ::cfmakeraw(&settings);
  settings.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | PARENB | CRTSCTS | CSIZE);
  settings.c_cflag |= CS8 | CLOCAL | CREAD;
  settings.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  settings.c_cc[VMIN] = 0;
  settings.c_cc[VTIME] = 0;
  if (::cfsetispeed(&settings, speed) != 0 || ::cfsetospeed(&settings, speed) != 0 ||
      ::tcsetattr(fd, TCSANOW, &settings) != 0) {
    error = errno;
    return false;
  }
  return true;
}

}  // namespace

SerialPort::~SerialPort() {
  close();
}

bool SerialPort::supported_baud(std::uint32_t baud) noexcept {
  speed_t speed = 0;
  return speed_of(baud, speed);
}

std::string SerialPort::open(const std::string& path, std::uint32_t baud) {
  close();
  speed_t speed = 0;
  if (!speed_of(baud, speed)) {
    return "serial port " + path + ": " + std::to_string(baud) +
           " baud is not a rate termios can set";
  }
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    return "serial port " + path + ": " + error_text(errno);
  }
  if (!::isatty(fd)) {
    ::close(fd);
    return "serial port " + path + ": not a terminal device";
  }
  int error = 0;
  if (::ioctl(fd, TIOCEXCL) != 0 || !configure_raw(fd, speed, error)) {
    error = error != 0 ? error : errno;
    ::close(fd);
    return "serial port " + path + ": " + error_text(error);
  }
  // What arrived before we were listening belongs to no telegram we can frame.
  ::tcflush(fd, TCIOFLUSH);
  fd_ = fd;
  path_ = path;
  baud_ = baud;
  return {};
}

void SerialPort::close() noexcept {
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
}

ReadResult SerialPort::do_read(std::span<std::uint8_t> buffer, TimestampNs timeout_ns) {
  if (fd_ < 0) {
    return {IoStatus::kDeviceLost, 0, 0};
  }
  pollfd waiting{fd_, POLLIN, 0};
  const int ready = ::poll(&waiting, 1, poll_timeout_ms(timeout_ns));
  if (ready == 0) {
    return {timeout_ns > 0 ? IoStatus::kTimedOut : IoStatus::kWouldBlock, 0, 0};
  }
  if (ready < 0) {
    return {errno == EINTR ? IoStatus::kWouldBlock : IoStatus::kIoError, 0, 0};
  }
  const ssize_t n = ::read(fd_, buffer.data(), buffer.size());
  if (n > 0) {
    return {IoStatus::kOk, static_cast<std::size_t>(n), clock_now_ns()};
  }
  if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
    return {IoStatus::kWouldBlock, 0, 0};
  }
  // Readable but nothing to read is a hang-up; so are EIO and ENXIO (the adapter unplugged,
  // the pseudo-terminal's other end closed).
  if (n == 0 || device_gone(errno) || (waiting.revents & (POLLHUP | POLLERR)) != 0) {
    return {IoStatus::kDeviceLost, 0, 0};
  }
  return {IoStatus::kIoError, 0, 0};
}

WriteResult SerialPort::do_write(std::span<const std::uint8_t> bytes, TimestampNs timeout_ns) {
  if (fd_ < 0) {
    return {IoStatus::kDeviceLost, 0};
  }
  const TimestampNs deadline_ns = clock_now_ns() + timeout_ns;
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + written, bytes.size() - written);
    if (n > 0) {
      written += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      return {device_gone(errno) ? IoStatus::kDeviceLost : IoStatus::kIoError, written};
    }
    // The kernel's buffer is full (the line drains at its baud rate): wait for room.
    const TimestampNs left_ns = deadline_ns - clock_now_ns();
    if (left_ns <= 0) {
      break;
    }
    pollfd waiting{fd_, POLLOUT, 0};
    if (::poll(&waiting, 1, poll_timeout_ms(left_ns)) == 0) {
      break;
    }
    if ((waiting.revents & (POLLHUP | POLLERR)) != 0) {
      return {IoStatus::kDeviceLost, written};
    }
  }
  if (written > 0) {
    return {IoStatus::kOk, written};
  }
  return {timeout_ns > 0 ? IoStatus::kTimedOut : IoStatus::kWouldBlock, 0};
}

IoStatus SerialPort::do_set_baud(std::uint32_t baud) {
  speed_t speed = 0;
  if (!speed_of(baud, speed)) {
    return IoStatus::kInvalidArgument;
  }
  if (fd_ < 0) {
    return IoStatus::kDeviceLost;
  }
  termios settings{};
  // TCSADRAIN: what was written at the old rate goes out at the old rate (the LMS2xx answers
  // a baud-change request at the rate it was asked at).
  if (::tcgetattr(fd_, &settings) != 0 || ::cfsetispeed(&settings, speed) != 0 ||
      ::cfsetospeed(&settings, speed) != 0 || ::tcsetattr(fd_, TCSADRAIN, &settings) != 0) {
    return device_gone(errno) ? IoStatus::kDeviceLost : IoStatus::kIoError;
  }
  baud_ = baud;
  return IoStatus::kOk;
}

}  // namespace blockmap::hal::linux_backend
