#include "blockmap/hal/linux/udp_sender.hpp"

#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <memory>
#include <system_error>

namespace blockmap::hal::linux_backend {

UdpSender::~UdpSender() {
  if (fd_ >= 0) {
    ::close(fd_);
  }
}

std::string UdpSender::check_destination(const std::string& destination) {
  const std::size_t colon = destination.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == destination.size()) {
    return "UDP destination '" + destination + "' is not HOST:PORT";
  }
  const std::string port = destination.substr(colon + 1);
  constexpr std::size_t kMaxPortDigits = 5;
  const bool digits =
      port.size() <= kMaxPortDigits && port.find_first_not_of("0123456789") == std::string::npos;
  constexpr int kMaxPort = 65535;
  const int number = digits ? std::stoi(port) : 0;
  if (number < 1 || number > kMaxPort) {
    return "UDP destination '" + destination + "': the port must be 1 to 65535";
  }
  return {};
}

std::string UdpSender::open(const std::string& destination) {
  if (std::string problem = check_destination(destination); !problem.empty()) {
    return problem;
  }
  const std::size_t colon = destination.rfind(':');
  const std::string host = destination.substr(0, colon);
  const std::string port = destination.substr(colon + 1);
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  if (const int error = ::getaddrinfo(host.c_str(), port.c_str(), &hints, &found); error != 0) {
    return "UDP destination '" + destination + "': " + ::gai_strerror(error);
  }
  const std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> addresses(found, &::freeaddrinfo);
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    return "UDP socket: " + std::error_code(errno, std::generic_category()).message();
  }
  // connect() fixes the destination: send() needs no address, and errors come back.
  if (::connect(fd, addresses->ai_addr, addresses->ai_addrlen) != 0) {
    const std::string reason = std::error_code(errno, std::generic_category()).message();
    ::close(fd);
    return "UDP destination '" + destination + "': " + reason;
  }
  fd_ = fd;
  return {};
}

bool UdpSender::send(std::span<const std::uint8_t> bytes) noexcept {
  if (fd_ < 0) {
    return false;
  }
  if (bytes.size() > kMaxDatagramBytes) {
    ++too_big_;
    return false;
  }
  const ssize_t written = ::send(fd_, bytes.data(), bytes.size(), MSG_DONTWAIT);
  if (written != static_cast<ssize_t>(bytes.size())) {
    ++dropped_;  // a full socket buffer, or the peer's port closed (ECONNREFUSED)
    return false;
  }
  ++sent_;
  return true;
}

}  // namespace blockmap::hal::linux_backend
