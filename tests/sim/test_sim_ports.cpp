// The simulated ports behave like the real ones they stand for: time passes on the wire, faults
// are injected as configured and counted, filters act like SocketCAN's.
#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "blockmap/hal/sim/loopback_can_bus.hpp"
#include "blockmap/hal/sim/scripted_byte_stream.hpp"
#include "blockmap/hal/sim/sim_gpio_line.hpp"
#include "byte_streams.hpp"

namespace blockmap::hal::sim {
namespace {

TEST(ScriptedByteStream, DeliversTheScriptInChunksAtTheLineRate) {
  // Given 480 bytes on a 4800 baud line
  const std::vector<std::uint8_t> script(480, 0x55);
  ManualClock clock;
  std::array<std::uint8_t, 16> written{};
  ScriptedStreamConfig config;
  config.baud = 4800;
  config.max_chunk_bytes = 50;
  ScriptedByteStream stream(script, clock, config, written);
  // When the host reads until the stream ends
  std::array<std::uint8_t, 64> buffer{};
  std::size_t total = 0;
  ReadResult result;
  while ((result = stream.read(buffer, 0)).status == IoStatus::kOk) {
    EXPECT_GE(result.bytes, 1u);
    EXPECT_LE(result.bytes, 50u);
    EXPECT_EQ(result.stamp_ns, clock.now_ns());
    total += result.bytes;
  }
  // Then every byte arrived, one second of line time passed, and the end reads as closed
  EXPECT_EQ(total, 480u);
  EXPECT_EQ(clock.now_ns(), kNanosecondsPerSecond);
  EXPECT_EQ(result.status, IoStatus::kClosed);
  EXPECT_EQ(stream.bytes_read(), 480u);
}

TEST(ScriptedByteStream, InjectsAndCountsDamage) {
  const std::vector<std::uint8_t> script(20'000, 0x41);
  ManualClock clock;
  std::array<std::uint8_t, 16> written{};
  ScriptedStreamConfig config;
  config.seed = 5;
  config.bit_flip_probability = 0.01;
  config.drop_probability = 0.01;
  config.garbage_probability = 0.1;
  ScriptedByteStream stream(script, clock, config, written);
  std::array<std::uint8_t, 128> buffer{};
  std::size_t delivered = 0;
  std::size_t changed = 0;
  for (ReadResult r; (r = stream.read(buffer, 0)).status == IoStatus::kOk;) {
    delivered += r.bytes;
    for (std::size_t i = 0; i < r.bytes; ++i) changed += buffer[i] != 0x41 ? 1U : 0U;
  }
  EXPECT_GT(stream.injected_bit_flips(), 100u);
  EXPECT_GT(stream.injected_drops(), 100u);
  EXPECT_GT(stream.injected_garbage_bytes(), 100u);
  EXPECT_EQ(delivered, 20'000 - stream.injected_drops() + stream.injected_garbage_bytes());
  EXPECT_GE(changed, stream.injected_bit_flips());
}

TEST(ScriptedByteStream, RecordsWhatTheHostWrites) {
  ManualClock clock;
  std::array<std::uint8_t, 4> written{};
  ScriptedByteStream stream({}, clock, ScriptedStreamConfig{}, written);
  const std::array<std::uint8_t, 6> command = {1, 2, 3, 4, 5, 6};
  EXPECT_EQ(stream.write(command, 0).bytes, 6u);
  ASSERT_EQ(stream.written().size(), 4u);
  EXPECT_EQ(stream.written().front(), 3) << "the oldest bytes make room";
  EXPECT_EQ(stream.written().dropped_oldest().value(), 2u);
  EXPECT_EQ(stream.set_baud(38400), IoStatus::kOk);
}

CanFrame frame(std::uint32_t id, std::uint8_t first_byte = 0) {
  CanFrame f;
  f.id = id;
  f.dlc = 8;
  f.data[0] = first_byte;
  return f;
}

TEST(LoopbackCanBus, DeliversInOrderAfterTheDelayAndAppliesFilters) {
  ManualClock clock(1000);
  std::array<PendingCanFrame, 8> pending{};
  std::array<CanFrame, 4> sent{};
  LoopbackCanConfig config;
  config.delay_ns = 500;
  LoopbackCanBus bus(clock, config, pending, sent);
  const std::array<CanFilter, 1> status_group = {CanFilter{0x400, 0x7F8}};
  ASSERT_EQ(bus.set_filters(status_group), IoStatus::kOk);
  ASSERT_EQ(bus.inject(frame(0x401, 1)), IoStatus::kOk);
  ASSERT_EQ(bus.inject(frame(0x688)), IoStatus::kOk);  // filtered out
  ASSERT_EQ(bus.inject(frame(0x402, 2)), IoStatus::kOk);
  CanFrame received;
  EXPECT_EQ(bus.receive(received, 0).status, IoStatus::kWouldBlock) << "still on the wire";
  (void)clock.advance_ns(500);
  CanReceiveResult result = bus.receive(received, 0);
  ASSERT_EQ(result.status, IoStatus::kOk);
  EXPECT_EQ(received.id, 0x401u);
  EXPECT_EQ(result.stamp_ns, 1500);
  ASSERT_EQ(bus.receive(received, 0).status, IoStatus::kOk);
  EXPECT_EQ(received.id, 0x402u);
  EXPECT_EQ(bus.receive(received, 0).status, IoStatus::kWouldBlock);
  EXPECT_EQ(bus.frames_received(), 2u);
}

TEST(LoopbackCanBus, BusOffLosesTheDeviceAndFullBufferOverflows) {
  ManualClock clock;
  std::array<PendingCanFrame, 2> pending{};
  std::array<CanFrame, 2> sent{};
  LoopbackCanBus bus(clock, LoopbackCanConfig{}, pending, sent);
  EXPECT_EQ(bus.inject(frame(0x401)), IoStatus::kOk);
  EXPECT_EQ(bus.inject(frame(0x402)), IoStatus::kOk);
  EXPECT_EQ(bus.inject(frame(0x403)), IoStatus::kOverflow);
  EXPECT_EQ(bus.pending().rejected_newest().value(), 1u);
  bus.set_bus_off(true);
  CanFrame received;
  EXPECT_EQ(bus.receive(received, 0).status, IoStatus::kDeviceLost);
  EXPECT_EQ(bus.send(frame(0x413)), IoStatus::kDeviceLost);
  EXPECT_EQ(bus.failures(), 2u);
  bus.set_bus_off(false);
  EXPECT_EQ(bus.send(frame(0x413)), IoStatus::kOk);
  EXPECT_EQ(bus.sent().back().id, 0x413u);
  CanFrame bad = frame(0x800);
  EXPECT_EQ(bus.send(bad), IoStatus::kInvalidArgument) << "not an 11-bit identifier";
}

TEST(LoopbackCanBus, DropsAndDuplicatesAtTheConfiguredRates) {
  ManualClock clock;
  std::vector<PendingCanFrame> pending(4000);
  std::array<CanFrame, 1> sent{};
  LoopbackCanConfig config;
  config.drop_probability = 0.1;
  config.duplicate_probability = 0.1;
  LoopbackCanBus bus(clock, config, pending, sent);
  for (int i = 0; i < 1000; ++i) {
    ASSERT_EQ(bus.inject(frame(0x401)), IoStatus::kOk);
  }
  EXPECT_NEAR(static_cast<double>(bus.injected_drops()), 100.0, 40.0);
  EXPECT_NEAR(static_cast<double>(bus.injected_duplicates()), 90.0, 40.0);
  EXPECT_EQ(bus.pending().size(), 1000 - bus.injected_drops() + bus.injected_duplicates());
}

TEST(SimGpioLine, QueuesEdgesWithTheirTimes) {
  std::array<GpioEdge, 4> storage{};
  SimGpioLine line(storage);
  line.drive(true, 100);
  line.drive(true, 150);  // no change, no edge
  line.drive(false, 200);
  GpioEdge edge = line.wait_edge(0);
  ASSERT_EQ(edge.status, IoStatus::kOk);
  EXPECT_TRUE(edge.rising);
  EXPECT_EQ(edge.stamp_ns, 100);
  edge = line.wait_edge(0);
  EXPECT_FALSE(edge.rising);
  EXPECT_EQ(edge.stamp_ns, 200);
  EXPECT_EQ(line.wait_edge(0).status, IoStatus::kWouldBlock);
  EXPECT_EQ(line.edges(), 2u);
  EXPECT_EQ(line.set(true), IoStatus::kOk);
  bool level = false;
  EXPECT_EQ(line.get(level), IoStatus::kOk);
  EXPECT_TRUE(level);
}

}  // namespace
}  // namespace blockmap::hal::sim
