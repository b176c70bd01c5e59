// Laser scanners on simulated serial lines, Given/When/Then: the start commands the device is
// sent, and the scans it publishes from the replies a real sensor gives.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/sim/scripted_byte_stream.hpp"
#include "blockmap/hal/sim/scripted_usb_bulk.hpp"
#include "test_data.hpp"

namespace blockmap::hal::devices {
namespace {

namespace lms = protocol::sick_lms2xx;
namespace scip2 = protocol::hokuyo_scip2;

template <typename Device>
std::vector<msg::LaserScan> poll_until_closed(Device& device, SpscQueueRef<msg::LaserScan>& queue) {
  std::vector<msg::LaserScan> scans;
  while (device.poll(0) == IoStatus::kOk) {
    for (msg::LaserScan scan; queue.try_pop(scan);) scans.push_back(scan);
  }
  for (msg::LaserScan scan; queue.try_pop(scan);) scans.push_back(scan);
  return scans;
}

TEST(Lms2xxScanner, StartsContinuousOutputAndPublishesEveryScan) {
  // Given an LMS291 at 38400 baud that acknowledges the mode switch and then streams scans
  std::vector<std::uint8_t> script = {lms::kAckByte};
  std::array<std::uint8_t, 64> reply{};
  const std::array<std::uint8_t, 1> accepted = {0x00};
  std::size_t n = lms::encode_reply(reply, lms::command::kSwitchModeReply, accepted, 0x10);
  script.insert(script.end(), reply.begin(), reply.begin() + static_cast<std::ptrdiff_t>(n));
  std::vector<std::uint16_t> values(361);
  std::vector<std::uint8_t> telegram(900);
  for (std::uint16_t s = 0; s < 5; ++s) {
    for (std::size_t i = 0; i < values.size(); ++i)
      values[i] = static_cast<std::uint16_t>(1000U + s * 10U + i);
    n = lms::encode_measured_values(telegram, values, lms::Units::kMm, 0x10);
    script.insert(script.end(), telegram.begin(),
                  telegram.begin() + static_cast<std::ptrdiff_t>(n));
  }
  sim::ManualClock clock;
  std::array<std::uint8_t, 64> written{};
  sim::ScriptedStreamConfig line;
  line.baud = 38400;
  sim::ScriptedByteStream port(script, clock, line, written);
  SpscQueue<msg::LaserScan, 8> queue;
  Lms2xxScannerConfig config;
  config.latency_ns = 20'000'000;
  Lms2xxScanner scanner(port, queue, config);
  // When the device starts it and reads the line to its end
  ASSERT_EQ(scanner.start(), IoStatus::kOk);
  const std::vector<msg::LaserScan> scans = poll_until_closed(scanner, queue);
  // Then the host sent exactly "continuous output" (docs/protocols.md 2.3) and got every scan
  const std::vector<std::uint8_t> expected_request = {0x02, 0x00, 0x02, 0x00,
                                                      0x20, 0x24, 0x34, 0x08};
  ASSERT_EQ(port.written().size(), expected_request.size());
  for (std::size_t i = 0; i < expected_request.size(); ++i)
    EXPECT_EQ(port.written()[i], expected_request[i]);
  EXPECT_EQ(scanner.decoder().acks(), 1u);
  EXPECT_EQ(scanner.mode_switches(), 1u);
  ASSERT_EQ(scans.size(), 5u);
  for (std::size_t s = 0; s < scans.size(); ++s) {
    EXPECT_EQ(scans[s].beam_count, 361);
    EXPECT_NEAR(scans[s].ranges_m[0], 1.0 + 0.01 * static_cast<double>(s), 1e-6);
    EXPECT_NEAR(scans[s].start_angle_rad, -1.5707963267948966, 1e-12);
  }
  // 732-byte telegrams at 38400 baud: 190 ms apart on the wire, each stamped when the read that
  // held its first byte returned (reads of up to 64 bytes: 16.7 ms), back-dated by 20 ms
  EXPECT_NEAR(static_cast<double>(scans[1].header.stamp_ns - scans[0].header.stamp_ns),
              732 * 10 / 38400.0 * 1e9, 64 * 10 / 38400.0 * 1e9);
  EXPECT_LT(scans[0].header.stamp_ns, 1'000'000'000LL * (1 + 22) * 10 / 38400);
}

std::string text(std::span<const char> chars, std::size_t length) {
  return {chars.data(), length};
}

TEST(UrgScanner, SwitchesToScip2ReadsGeometryAndStreams) {
  // Given a URG-04LX that answers the start commands and then sends three MD scans
  std::string replies = "SCIP2.0\n0\n\nPP\n00P\n";
  for (const auto& [name, value] : {std::pair{"DMIN", "20"},
                                    {"DMAX", "5600"},
                                    {"ARES", "1024"},
                                    {"AMIN", "44"},
                                    {"AMAX", "725"},
                                    {"AFRT", "384"},
                                    {"SCAN", "600"}}) {
    const std::string line = std::string(name) + ":" + value;
    replies += line + ";" + scip2::checksum(line) + "\n";
  }
  replies += "\nBM\n00P\n\nMD0044072501000\n00P\n\n";
  std::vector<char> out(8192);
  const std::vector<std::uint32_t> values(682, 2500);
  for (std::uint32_t s = 0; s < 3; ++s) {
    replies +=
        text(out, scip2::encode_scan_reply(out, "MD0044072501000", "99", 1000 + 100 * s, values));
  }
  const std::vector<std::uint8_t> script(replies.begin(), replies.end());
  sim::ManualClock clock;
  std::array<std::uint8_t, 128> written{};
  sim::ScriptedByteStream port(script, clock, sim::ScriptedStreamConfig{}, written);
  SpscQueue<msg::LaserScan, 8> queue;
  UrgScanner scanner(port, queue, UrgScannerConfig{});
  // When started and read to the end
  ASSERT_EQ(scanner.start(), IoStatus::kOk);
  const std::vector<msg::LaserScan> scans = poll_until_closed(scanner, queue);
  // Then it sent the documented sequence and published each scan with the sensor's geometry
  std::string sent;
  for (std::size_t i = 0; i < port.written().size(); ++i)
    sent += static_cast<char>(port.written()[i]);
  EXPECT_EQ(sent, "SCIP2.0\nPP\nBM\nMD0044072501000\n");
  ASSERT_EQ(scans.size(), 3u);
  EXPECT_EQ(scans[2].scan_counter, 1200u);
  EXPECT_EQ(scans[0].beam_count, 682);
  EXPECT_NEAR(scans[0].start_angle_rad, (44.0 - 384.0) * 2.0 * 3.141592653589793 / 1024.0, 1e-12);
  EXPECT_FLOAT_EQ(scans[1].ranges_m[100], 2.5F);
  EXPECT_EQ(scanner.error_replies(), 0u);
}

TEST(TimScanner, EnablesScanEventsAndSurvivesAnUnplug) {
  // Given a TiM on USB whose IN endpoint delivers 16 real scans, re-encoded as CoLa A
  namespace cola = protocol::sick_cola;
  const auto binary =
      testing::read_bytes(testing::project_data("cola/sick_scan_xd_test_pcapng_all16_frames.bin"));
  cola::StaticDecoder<> reader;
  std::vector<std::uint8_t> script;
  std::vector<std::uint8_t> telegram(cola::kDefaultTelegramCapacityBytes);
  std::vector<std::uint16_t> first_ranges_mm;
  std::span<const std::uint8_t> rest(binary);
  for (;;) {
    const auto step = reader.push(rest, 0);
    rest = rest.subspan(step.consumed);
    if (step.scan != nullptr) {
      const std::size_t n = cola::encode_scan(cola::Dialect::kColaA, *step.scan,
                                              cola::ScanTelegramFields{}, telegram);
      script.insert(script.end(), telegram.begin(),
                    telegram.begin() + static_cast<std::ptrdiff_t>(n));
      first_ranges_mm.push_back(
          static_cast<std::uint16_t>(std::lround(step.scan->ranges_m[400] * 1000.0F)));
    }
    if (!step.has_event() && rest.empty()) break;
  }
  ASSERT_EQ(first_ranges_mm.size(), 16u);
  sim::ManualClock clock;
  std::array<std::uint8_t, 128> sent{};
  sim::ScriptedUsbBulk usb(script, clock, 9, 512, sent);
  SpscQueue<msg::LaserScan, 32> queue;
  TimScanner scanner(usb, queue, TimScannerConfig{});
  // When it is started, unplugged for a while mid-stream, and read to the end
  ASSERT_EQ(scanner.start(), IoStatus::kOk);
  std::vector<msg::LaserScan> scans;
  for (int transfer = 0; !usb.finished(); ++transfer) {
    if (transfer == 40) usb.set_attached(false);
    if (transfer == 43) usb.set_attached(true);
    const IoStatus status = scanner.poll(kNanosecondsPerSecond);
    EXPECT_TRUE(status == IoStatus::kOk ||
                (status == IoStatus::kDeviceLost && transfer >= 40 && transfer < 43));
    for (msg::LaserScan scan; queue.try_pop(scan);) scans.push_back(scan);
  }
  // Then it sent "sEN LMDscandata 1" in CoLa A, lost only the scan the unplug cut in two (its
  // held bytes are flushed, its tail is dropped as garbage) and published all the others
  std::string command;
  for (std::size_t i = 0; i < usb.sent().size(); ++i) command += static_cast<char>(usb.sent()[i]);
  EXPECT_EQ(command, "\x02sEN LMDscandata 1\x03");
  ASSERT_EQ(scans.size(), 15u);
  std::size_t next = 0;
  for (const msg::LaserScan& scan : scans) {
    EXPECT_EQ(scan.beam_count, 811);
    const auto range_mm = static_cast<std::uint16_t>(std::lround(scan.ranges_m[400] * 1000.0F));
    while (next < first_ranges_mm.size() && first_ranges_mm[next] != range_mm) ++next;
    EXPECT_LT(next, first_ranges_mm.size()) << "scans arrive in order";
    ++next;
  }
  EXPECT_GT(scanner.decoder().drops().total(), 0u);
}

}  // namespace
}  // namespace blockmap::hal::devices
