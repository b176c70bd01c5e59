// The plane stream over UDP: a record goes out as one datagram on the loopback interface; a
// destination that is not HOST:PORT is one clear line; a record too big for a datagram is
// counted, not sent.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "blockmap/hal/linux/udp_sender.hpp"

namespace blockmap::hal::linux_backend {
namespace {

// A UDP socket bound to a free port of 127.0.0.1.
class Receiver {
 public:
  Receiver() : fd_(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0)) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = 0;
    bound_ =
        fd_ >= 0 && ::bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0;
    socklen_t length = sizeof address;
    if (bound_ && ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &length) == 0) {
      port_ = ntohs(address.sin_port);
    }
    timeval timeout{2, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  }
  ~Receiver() {
    if (fd_ >= 0) {
      ::close(fd_);
    }
  }
  Receiver(const Receiver&) = delete;
  Receiver& operator=(const Receiver&) = delete;
  [[nodiscard]] bool ready() const { return bound_ && port_ != 0; }
  [[nodiscard]] std::uint16_t port() const { return port_; }
  std::vector<std::uint8_t> receive() {
    std::vector<std::uint8_t> bytes(70000);
    const ssize_t n = ::recv(fd_, bytes.data(), bytes.size(), 0);
    bytes.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
    return bytes;
  }

 private:
  int fd_;
  bool bound_ = false;
  std::uint16_t port_ = 0;
};

TEST(UdpSender, SendsEachRecordAsOneDatagram) {
  Receiver receiver;
  if (!receiver.ready()) {
    GTEST_SKIP() << "no loopback UDP socket on this machine";
  }
  UdpSender sender;
  ASSERT_EQ(sender.open("127.0.0.1:" + std::to_string(receiver.port())), "");
  const std::array<std::uint8_t, 5> record = {'B', 'M', 1, 2, 3};
  EXPECT_TRUE(sender.send(record));
  const std::vector<std::uint8_t> got = receiver.receive();
  EXPECT_EQ(got, std::vector<std::uint8_t>(record.begin(), record.end()));
  EXPECT_EQ(sender.sent(), 1u);
  // Bigger than any UDP datagram: counted and left out.
  const std::vector<std::uint8_t> huge(UdpSender::kMaxDatagramBytes + 1, 0);
  EXPECT_FALSE(sender.send(huge));
  EXPECT_EQ(sender.too_big(), 1u);
}

TEST(UdpSender, ABadDestinationIsOneClearLine) {
  UdpSender sender;
  EXPECT_NE(sender.open("localhost").find("is not HOST:PORT"), std::string::npos);
  EXPECT_NE(sender.open(":9000").find("is not HOST:PORT"), std::string::npos);
  EXPECT_NE(sender.open("127.0.0.1:no-such-service"), "");
  EXPECT_FALSE(sender.is_open());
  const std::array<std::uint8_t, 1> byte = {0};
  EXPECT_FALSE(sender.send(byte));
}

}  // namespace
}  // namespace blockmap::hal::linux_backend
