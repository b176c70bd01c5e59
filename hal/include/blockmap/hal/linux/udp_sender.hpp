// The plane stream over UDP: each binary record (docs/log-formats.md, "Plane stream") goes out
// as one datagram to a configured host and port, so that a base station or a teammate's
// viewer can follow the map live. Sending never blocks the pipeline: a datagram the kernel
// cannot take now is dropped and counted, as is a record too big for one datagram.
#pragma once

#include <cstdint>
#include <span>
#include <string>

namespace blockmap::hal::linux_backend {

class UdpSender {
 public:
  // The largest UDP payload over IPv4.
  static constexpr std::size_t kMaxDatagramBytes = 65507;

  UdpSender() = default;
  ~UdpSender();
  UdpSender(const UdpSender&) = delete;
  UdpSender& operator=(const UdpSender&) = delete;

  // Whether `destination` reads as HOST:PORT with a port of 1 to 65535, before any lookup:
  // empty when it does, otherwise why not.
  [[nodiscard]] static std::string check_destination(const std::string& destination);
  // `destination` is HOST:PORT (a name or an IPv4 address). Empty when it worked, otherwise
  // why not.
  [[nodiscard]] std::string open(const std::string& destination);
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }
  // One datagram; false (counted) when it was not sent.
  bool send(std::span<const std::uint8_t> bytes) noexcept;

  [[nodiscard]] std::uint64_t sent() const noexcept { return sent_; }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_; }
  [[nodiscard]] std::uint64_t too_big() const noexcept { return too_big_; }

 private:
  int fd_ = -1;
  std::uint64_t sent_ = 0;
  std::uint64_t dropped_ = 0;
  std::uint64_t too_big_ = 0;
};

}  // namespace blockmap::hal::linux_backend
