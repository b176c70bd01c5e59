#include "blockmap/hal/linux/socket_can_bus.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>

#include "descriptor_wait.hpp"

namespace blockmap::hal::linux_backend {
namespace {

bool interface_gone(int error) noexcept {
  return error == ENETDOWN || error == ENODEV || error == ENXIO || error == EBADF;
}

// The kernel's receive stamp (realtime) on the monotonic clock: shifted by the two clocks'
// offset now, which moves only with time steps (NTP slews keep it within microseconds).
TimestampNs monotonic_stamp(const timespec& realtime) noexcept {
  const TimestampNs stamp_real =
      static_cast<TimestampNs>(realtime.tv_sec) * 1'000'000'000 + realtime.tv_nsec;
  const TimestampNs now_mono = clock_now_ns();
  const TimestampNs now_real = clock_now_ns(CLOCK_REALTIME);
  return now_mono - (now_real - stamp_real);
}

}  // namespace

SocketCanBus::~SocketCanBus() {
  close();
}

std::string SocketCanBus::open(const std::string& interface) {
  close();
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    return "CAN interface '" + interface + "': a name of 1 to 15 characters";
  }
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    return "CAN interface " + interface + ": no CAN socket (" + error_text(errno) +
           "; is the can-raw module loaded?)";
  }
  const auto fail = [&](const std::string& what) {
    std::string message = "CAN interface " + interface + ": " + what + error_text(errno);
    ::close(fd);
    return message;
  };
  ifreq request{};
  std::memcpy(request.ifr_name, interface.c_str(), interface.size() + 1);
  if (::ioctl(fd, SIOCGIFINDEX, &request) != 0) {
    return fail("");
  }
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = request.ifr_ifindex;
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    return fail("bind: ");
  }
  const can_err_mask_t errors = CAN_ERR_MASK;
  const int on = 1;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors) != 0 ||
      ::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) {
    return fail("socket options: ");
  }
  fd_ = fd;
  interface_ = interface;
  return {};
}

void SocketCanBus::close() noexcept {
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
}

CanReceiveResult SocketCanBus::do_receive(CanFrame& frame, TimestampNs timeout_ns) {
  if (fd_ < 0) {
    return {IoStatus::kDeviceLost, 0};
  }
  pollfd waiting{fd_, POLLIN, 0};
  const int ready = ::poll(&waiting, 1, poll_timeout_ms(timeout_ns));
  if (ready == 0) {
    return {timeout_ns > 0 ? IoStatus::kTimedOut : IoStatus::kWouldBlock, 0};
  }
  if (ready < 0) {
    return {errno == EINTR ? IoStatus::kWouldBlock : IoStatus::kIoError, 0};
  }
  can_frame raw{};
  iovec part{&raw, sizeof raw};
  alignas(cmsghdr) std::array<char, CMSG_SPACE(sizeof(timespec))> control{};
  msghdr message{};
  message.msg_iov = &part;
  message.msg_iovlen = 1;
  message.msg_control = control.data();
  message.msg_controllen = control.size();
  const ssize_t n = ::recvmsg(fd_, &message, 0);
  if (n < 0) {
    if (errno == EAGAIN || errno == EINTR) {
      return {IoStatus::kWouldBlock, 0};
    }
    return {interface_gone(errno) ? IoStatus::kDeviceLost : IoStatus::kIoError, 0};
  }
  if (static_cast<std::size_t>(n) < sizeof raw) {
    return {IoStatus::kBadData, 0};
  }
  TimestampNs stamp_ns = clock_now_ns();
  for (cmsghdr* header = CMSG_FIRSTHDR(&message); header != nullptr;
       header = CMSG_NXTHDR(&message, header)) {
    if (header->cmsg_level == SOL_SOCKET && header->cmsg_type == SCM_TIMESTAMPNS) {
      timespec realtime{};
      std::memcpy(&realtime, CMSG_DATA(header), sizeof realtime);
      stamp_ns = monotonic_stamp(realtime);
    }
  }
  frame.extended = (raw.can_id & CAN_EFF_FLAG) != 0;
  frame.remote = (raw.can_id & CAN_RTR_FLAG) != 0;
  frame.error = (raw.can_id & CAN_ERR_FLAG) != 0;
  frame.id = raw.can_id & (frame.extended || frame.error ? CAN_EFF_MASK : CAN_SFF_MASK);
  frame.dlc = std::min<std::uint8_t>(raw.len, 8);
  std::copy_n(raw.data, frame.dlc, frame.data.begin());
  if (frame.error && (raw.can_id & CAN_ERR_BUSOFF) != 0) {
    ++bus_off_;
    return {IoStatus::kDeviceLost, stamp_ns};
  }
  return {IoStatus::kOk, stamp_ns};
}

IoStatus SocketCanBus::do_send(const CanFrame& frame) {
  if (fd_ < 0) {
    return IoStatus::kDeviceLost;
  }
  can_frame raw{};
  raw.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0U) | (frame.remote ? CAN_RTR_FLAG : 0U);
  raw.len = frame.dlc;
  std::copy_n(frame.data.begin(), frame.dlc, raw.data);
  const ssize_t n = ::write(fd_, &raw, sizeof raw);
  if (n == static_cast<ssize_t>(sizeof raw)) {
    return IoStatus::kOk;
  }
  // ENOBUFS: the interface's transmit queue is full (a bus that does not acknowledge).
  if (n < 0 && (errno == EAGAIN || errno == ENOBUFS || errno == EINTR)) {
    return IoStatus::kWouldBlock;
  }
  return n < 0 && interface_gone(errno) ? IoStatus::kDeviceLost : IoStatus::kIoError;
}

IoStatus SocketCanBus::do_set_filters(std::span<const CanFilter> filters) {
  if (fd_ < 0) {
    return IoStatus::kDeviceLost;
  }
  if (filters.size() > kMaxFilters) {
    return IoStatus::kInvalidArgument;
  }
  std::array<can_filter, kMaxFilters> raw{};
  for (std::size_t i = 0; i < filters.size(); ++i) {
    raw[i].can_id = filters[i].id;
    raw[i].can_mask = filters[i].mask;
  }
  // No filters: every frame (the kernel's default is one filter that passes all).
  can_filter everything{0, 0};
  const void* table = filters.empty() ? static_cast<const void*>(&everything) : raw.data();
  const auto bytes = static_cast<socklen_t>(filters.empty() ? sizeof everything
                                                            : filters.size() * sizeof(can_filter));
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, table, bytes) != 0) {
    return interface_gone(errno) ? IoStatus::kDeviceLost : IoStatus::kIoError;
  }
  return IoStatus::kOk;
}

}  // namespace blockmap::hal::linux_backend
