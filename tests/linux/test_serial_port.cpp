// The termios serial port (hal/linux/serial_port.hpp) on a real kernel tty: a pseudo-terminal,
// whose far end (the master) plays the device. Raw 8N1 both ways, the LMS2xx's 500 kBd, clear
// errors, and kDeviceLost when the device goes away.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/linux/serial_port.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "test_units.hpp"

namespace blockmap::hal::linux_backend {
namespace {

using blockmap::testing::kMs;

// A pseudo-terminal pair: the port opens the slave's path; the test talks through the master.
class PseudoTerminal {
 public:
  PseudoTerminal() {
    std::array<char, 128> name{};
    if (::openpty(&master_, &slave_, name.data(), nullptr, nullptr) == 0) {
      path_ = name.data();
    }
  }
  ~PseudoTerminal() {
    close_master();
    if (slave_ >= 0) {
      ::close(slave_);
    }
  }
  PseudoTerminal(const PseudoTerminal&) = delete;
  PseudoTerminal& operator=(const PseudoTerminal&) = delete;

  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] int slave() const { return slave_; }
  [[nodiscard]] int master() const { return master_; }
  void close_master() {
    if (master_ >= 0) {
      ::close(master_);
      master_ = -1;
    }
  }
  void send(const std::vector<std::uint8_t>& bytes) const {
    ASSERT_EQ(::write(master_, bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size()));
  }
  // What the port wrote, waiting up to a second for `count` bytes.
  [[nodiscard]] std::vector<std::uint8_t> receive(std::size_t count) const {
    std::vector<std::uint8_t> bytes;
    std::array<std::uint8_t, 512> chunk{};
    for (int waits = 0; bytes.size() < count && waits < 100; ++waits) {
      pollfd waiting{master_, POLLIN, 0};
      if (::poll(&waiting, 1, 10) > 0) {
        const ssize_t n = ::read(master_, chunk.data(), chunk.size());
        if (n > 0) {
          bytes.insert(bytes.end(), chunk.begin(), chunk.begin() + n);
        }
      }
    }
    return bytes;
  }

 private:
  int master_ = -1;
  int slave_ = -1;
  std::string path_;
};

// Everything the port reads within a second, until `count` bytes.
std::vector<std::uint8_t> read_all(SerialPort& port, std::size_t count) {
  std::vector<std::uint8_t> bytes;
  std::array<std::uint8_t, 512> buffer{};
  for (int reads = 0; bytes.size() < count && reads < 100; ++reads) {
    const ReadResult result = port.read(buffer, 10 * kMs);
    if (result.status == IoStatus::kOk) {
      bytes.insert(bytes.end(), buffer.begin(),
                   buffer.begin() + static_cast<std::ptrdiff_t>(result.bytes));
    }
  }
  return bytes;
}

TEST(SerialPort, CarriesEveryByteValueUnchangedBothWays) {
  PseudoTerminal tty;
  ASSERT_FALSE(tty.path().empty()) << "no pseudo-terminal";
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 38400), "");
  // All 256 values: CR, LF, XON/XOFF, ^C and 0x00 must not be translated or swallowed (a
  // range reading of an LMS telegram can be any of them).
  std::vector<std::uint8_t> all(256);
  std::iota(all.begin(), all.end(), std::uint8_t{0});
  tty.send(all);
  EXPECT_EQ(read_all(port, all.size()), all);
  const WriteResult written = port.write(all, 100 * kMs);
  EXPECT_EQ(written.status, IoStatus::kOk);
  EXPECT_EQ(written.bytes, all.size());
  EXPECT_EQ(tty.receive(all.size()), all);
  EXPECT_EQ(port.bytes_read(), 256u);
  EXPECT_EQ(port.bytes_written(), 256u);
}

TEST(SerialPort, StampsReadsWithTheMonotonicClock) {
  PseudoTerminal tty;
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 9600), "");
  timespec before{};
  ::clock_gettime(CLOCK_MONOTONIC, &before);
  tty.send({'$', 'G', 'P'});
  std::array<std::uint8_t, 16> buffer{};
  const ReadResult result = port.read(buffer, 500 * kMs);
  ASSERT_EQ(result.status, IoStatus::kOk);
  timespec after{};
  ::clock_gettime(CLOCK_MONOTONIC, &after);
  const auto ns = [](const timespec& t) {
    return static_cast<TimestampNs>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
  };
  EXPECT_GE(result.stamp_ns, ns(before));
  EXPECT_LE(result.stamp_ns, ns(after));
}

TEST(SerialPort, RunsAtTheLaserRatesAndRefusesOthers) {
  PseudoTerminal tty;
  SerialPort port;
  // The LMS2xx's 500 kBd, which is no POSIX rate: termios's B500000.
  ASSERT_EQ(port.open(tty.path(), 500000), "");
  termios settings{};
  ASSERT_EQ(::tcgetattr(tty.slave(), &settings), 0);
  // QEMU's user mode (the cross trees' test runner; 7.2 in bookworm) does not translate the
  // speeds above 460800 between the guest's termios and the host's, and reads them back as 0
  // (B0, which no successful open leaves). A real kernel, the guest system tests' included,
  // reads back what was set; a speed that was not set at all would read back the tty's
  // default, 38400.
  const speed_t fast = ::cfgetospeed(&settings);
  if (fast != 0) {
    EXPECT_EQ(fast, static_cast<speed_t>(B500000));
  }
  EXPECT_EQ(settings.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
  EXPECT_EQ(settings.c_cflag & (PARENB | CSTOPB | CRTSCTS), 0u);
  EXPECT_EQ(settings.c_lflag & (ICANON | ECHO | ISIG), 0u);
  // The LMS2xx starts at 9600 and is asked to change: the port follows.
  EXPECT_EQ(port.set_baud(9600), IoStatus::kOk);
  ASSERT_EQ(::tcgetattr(tty.slave(), &settings), 0);
  EXPECT_EQ(::cfgetospeed(&settings), static_cast<speed_t>(B9600));
  EXPECT_EQ(port.baud(), 9600u);
  EXPECT_EQ(port.set_baud(12345), IoStatus::kInvalidArgument);
  EXPECT_EQ(port.baud(), 9600u);
  EXPECT_TRUE(SerialPort::supported_baud(4800));
  EXPECT_FALSE(SerialPort::supported_baud(0));
}

TEST(SerialPort, AQuietLineTimesOutAndAMissingDeviceIsOneClearLine) {
  PseudoTerminal tty;
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 4800), "");
  std::array<std::uint8_t, 16> buffer{};
  EXPECT_EQ(port.read(buffer, 20 * kMs).status, IoStatus::kTimedOut);
  EXPECT_EQ(port.read(buffer, 0).status, IoStatus::kWouldBlock);

  SerialPort missing;
  const std::string error = missing.open("/dev/ttyBLOCKMAP_NONE", 38400);
  EXPECT_NE(error.find("/dev/ttyBLOCKMAP_NONE"), std::string::npos) << error;
  EXPECT_NE(error.find("No such file"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
  EXPECT_FALSE(missing.is_open());
  EXPECT_NE(missing.open("/dev/null", 38400).find("not a terminal"), std::string::npos);
  EXPECT_NE(missing.open(tty.path(), 12345).find("12345 baud"), std::string::npos);
  EXPECT_EQ(missing.read(buffer, 0).status, IoStatus::kDeviceLost);
}

TEST(SerialPort, TheDeviceGoingAwayIsDeviceLostAndReopeningWorks) {
  auto tty = std::make_unique<PseudoTerminal>();
  SerialPort port;
  ASSERT_EQ(port.open(tty->path(), 38400), "");
  tty->send({0x02, 0x80});
  EXPECT_EQ(read_all(port, 2).size(), 2u);
  tty->close_master();  // the USB adapter pulled out
  std::array<std::uint8_t, 16> buffer{};
  EXPECT_EQ(port.read(buffer, 100 * kMs).status, IoStatus::kDeviceLost);
  EXPECT_EQ(port.failures(), 1u);
  // Plugged in again (a new device node): the owner closes and opens.
  tty = std::make_unique<PseudoTerminal>();
  ASSERT_EQ(port.open(tty->path(), 38400), "");
  tty->send({0x06});
  EXPECT_EQ(read_all(port, 1), std::vector<std::uint8_t>{0x06});
}

TEST(SerialPort, AnLms2xxScannerStartsAndStreamsThroughARealTerminal) {
  // The device layer on a real tty, with the bytes an LMS291 sends: the scanner asks for
  // continuous output, the "laser" (the test, at the master) acknowledges and streams.
  namespace lms = protocol::sick_lms2xx;
  PseudoTerminal tty;
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 38400), "");
  SpscQueue<msg::LaserScan, 8> queue;
  devices::Lms2xxScanner scanner(port, queue, devices::Lms2xxScannerConfig{});
  ASSERT_EQ(scanner.start(), IoStatus::kOk);
  const std::vector<std::uint8_t> continuous_output = {0x02, 0x00, 0x02, 0x00,
                                                       0x20, 0x24, 0x34, 0x08};
  EXPECT_EQ(tty.receive(continuous_output.size()), continuous_output);

  std::vector<std::uint8_t> answer = {lms::kAckByte};
  std::array<std::uint8_t, 64> reply{};
  const std::array<std::uint8_t, 1> accepted = {0x00};
  std::size_t n = lms::encode_reply(reply, lms::command::kSwitchModeReply, accepted, 0x10);
  answer.insert(answer.end(), reply.begin(), reply.begin() + static_cast<std::ptrdiff_t>(n));
  std::vector<std::uint16_t> values(361);
  std::vector<std::uint8_t> telegram(900);
  for (std::uint16_t s = 0; s < 4; ++s) {  // 4 x 732 bytes: within the tty's 4 KiB buffer
    for (std::size_t i = 0; i < values.size(); ++i) {
      values[i] = static_cast<std::uint16_t>(1000U + s * 10U + i);
    }
    n = lms::encode_measured_values(telegram, values, lms::Units::kMm, 0x10);
    answer.insert(answer.end(), telegram.begin(),
                  telegram.begin() + static_cast<std::ptrdiff_t>(n));
  }
  tty.send(answer);
  std::vector<msg::LaserScan> scans;
  for (int polls = 0; scans.size() < 4 && polls < 200; ++polls) {
    static_cast<void>(scanner.poll(10 * kMs));
    for (msg::LaserScan scan; queue.try_pop(scan);) {
      scans.push_back(scan);
    }
  }
  EXPECT_EQ(scanner.mode_switches(), 1u);
  ASSERT_EQ(scans.size(), 4u);
  for (std::size_t s = 0; s < scans.size(); ++s) {
    EXPECT_EQ(scans[s].beam_count, 361);
    EXPECT_NEAR(scans[s].ranges_m[0], 1.0 + 0.01 * static_cast<double>(s), 1e-6);
  }
  EXPECT_EQ(scanner.decoder().drops().total(), 0u);
  EXPECT_EQ(scanner.decoder().scans_decoded(), 4u);
}

// An LMS2xx at the master end for the baud-rate handshake (docs/protocols.md 2.4): it talks at
// `rate_bd` (9600 after power-up) and answers only requests sent at that rate, a mode switch
// with 06 and A0 00 (at the old rate, then it switches). It records each request and the line
// rate the port had set when it came.
class FakeLms {
 public:
  FakeLms(PseudoTerminal& tty, std::uint32_t rate_bd) : tty_(tty), rate_bd_(rate_bd) {
    thread_ = std::thread([this] { run(); });
  }
  ~FakeLms() {
    stop_ = true;
    thread_.join();
  }
  FakeLms(const FakeLms&) = delete;
  FakeLms& operator=(const FakeLms&) = delete;
  struct Request {
    std::vector<std::uint8_t> bytes;
    speed_t line = 0;  // the port's rate when it came (0 where QEMU cannot say)
  };
  [[nodiscard]] std::vector<Request> requests() {
    const std::lock_guard<std::mutex> guard(lock_);
    return requests_;
  }

 private:
  void run() {
    namespace lms = protocol::sick_lms2xx;
    while (!stop_) {
      const std::vector<std::uint8_t> request = tty_.receive(8);
      if (request.size() < 8) {
        continue;
      }
      termios line{};
      ::tcgetattr(tty_.master(), &line);
      const speed_t speed = ::cfgetospeed(&line);
      {
        const std::lock_guard<std::mutex> guard(lock_);
        requests_.push_back({request, speed});
      }
      const speed_t own = rate_bd_ == 9600 ? B9600 : B500000;
      // QEMU user mode reads B500000 back as 0: there the rate cannot be told, and the fake
      // answers what a scanner at its rate would, judging by the request alone.
      if (speed != own && speed != 0) {
        continue;  // at another rate the scanner sees noise and answers nothing
      }
      if (speed == 0 && request[5] == 0x24 && rate_bd_ != 500000) {
        continue;
      }
      std::vector<std::uint8_t> answer = {lms::kAckByte};
      std::array<std::uint8_t, 64> reply{};
      const std::array<std::uint8_t, 1> accepted = {0x00};
      const std::size_t n =
          lms::encode_reply(reply, lms::command::kSwitchModeReply, accepted, 0x10);
      answer.insert(answer.end(), reply.begin(), reply.begin() + static_cast<std::ptrdiff_t>(n));
      tty_.send(answer);
      if (request[4] == 0x20 && request[5] == 0x48) {
        rate_bd_ = 500000;  // the new rate, once the reply is out
      }
    }
  }

  PseudoTerminal& tty_;
  std::uint32_t rate_bd_;
  std::atomic<bool> stop_{false};
  std::mutex lock_;
  std::vector<Request> requests_;
  std::thread thread_;
};

const std::vector<std::uint8_t> kContinuousRequest = {0x02, 0x00, 0x02, 0x00,
                                                      0x20, 0x24, 0x34, 0x08};
const std::vector<std::uint8_t> kTo500kRequest = {0x02, 0x00, 0x02, 0x00, 0x20, 0x48, 0x58, 0x08};

devices::Lms2xxScannerConfig handshake_config() {
  devices::Lms2xxScannerConfig config;
  config.line_baud = 500000;
  config.power_up_baud = 9600;
  return config;
}

TEST(SerialPort, AnLms2xxAtItsPowerUpRateIsBroughtToTheLinesRate) {
  PseudoTerminal tty;
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 500000), "");
  SpscQueue<msg::LaserScan, 8> queue;
  devices::Lms2xxScanner scanner(port, queue, handshake_config());
  FakeLms laser(tty, 9600);  // just powered up
  ASSERT_EQ(scanner.start(), IoStatus::kOk);
  // Continuous output at 500 kBd (no answer), 500 kBd asked for at 9600 (answered), then
  // continuous output at 500 kBd (answered).
  const std::vector<FakeLms::Request> requests = laser.requests();
  ASSERT_EQ(requests.size(), 3u);
  EXPECT_EQ(requests[0].bytes, kContinuousRequest);
  EXPECT_EQ(requests[1].bytes, kTo500kRequest);
  EXPECT_EQ(requests[2].bytes, kContinuousRequest);
  if (requests[0].line != 0) {  // not under QEMU user mode
    EXPECT_EQ(requests[0].line, static_cast<speed_t>(B500000));
    EXPECT_EQ(requests[2].line, static_cast<speed_t>(B500000));
  }
  EXPECT_EQ(requests[1].line, static_cast<speed_t>(B9600));
  EXPECT_EQ(scanner.mode_switches(), 2u);
  EXPECT_EQ(port.baud(), 500000u);
}

TEST(SerialPort, AnLms2xxAlreadyAtTheLinesRateIsOnlyAskedForItsScans) {
  PseudoTerminal tty;
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 500000), "");
  SpscQueue<msg::LaserScan, 8> queue;
  devices::Lms2xxScanner scanner(port, queue, handshake_config());
  FakeLms laser(tty, 500000);  // kept the rate since the daemon's last start
  ASSERT_EQ(scanner.start(), IoStatus::kOk);
  const std::vector<FakeLms::Request> requests = laser.requests();
  ASSERT_EQ(requests.size(), 1u);
  EXPECT_EQ(requests[0].bytes, kContinuousRequest);
}

TEST(SerialPort, AnLms2xxThatAnswersAtNeitherRateTimesOut) {
  PseudoTerminal tty;
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 500000), "");
  SpscQueue<msg::LaserScan, 8> queue;
  devices::Lms2xxScanner scanner(port, queue, handshake_config());
  EXPECT_EQ(scanner.start(), IoStatus::kTimedOut);  // nobody at the other end
  EXPECT_EQ(port.baud(), 500000u) << "the port is left at the line's rate";
}

TEST(SerialPort, AGpsReceiverPublishesFixesFromNmeaOnARealTerminal) {
  // Two epochs of a receiver at 9600 baud, as it sends them (CR LF line ends: raw mode keeps
  // them).
  const std::string nmea =
      "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
      "$GPRMC,123520,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*60\r\n"
      "$GPGGA,123520,4807.040,N,01131.002,E,1,08,0.9,545.6,M,46.9,M,,*42\r\n";
  PseudoTerminal tty;
  SerialPort port;
  ASSERT_EQ(port.open(tty.path(), 9600), "");
  SpscQueue<msg::GpsFix, 8> fixes;
  devices::GpsReceiver receiver(port, fixes, devices::GpsReceiverConfig{});
  tty.send(std::vector<std::uint8_t>(nmea.begin(), nmea.end()));
  for (int polls = 0; receiver.fixes_published() < 2 && polls < 100; ++polls) {
    static_cast<void>(receiver.poll(10 * kMs));
  }
  ASSERT_EQ(receiver.fixes_published(), 2u);
  msg::GpsFix fix;
  ASSERT_TRUE(fixes.try_pop(fix));
  EXPECT_NEAR(fix.latitude_deg, 48.0 + 7.038 / 60.0, 1e-9);
  EXPECT_NEAR(fix.longitude_deg, 11.0 + 31.0 / 60.0, 1e-9);
  EXPECT_EQ(receiver.decoder().drops().total(), 0u);
}

}  // namespace
}  // namespace blockmap::hal::linux_backend
