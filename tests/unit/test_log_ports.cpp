// The ports over recorded logs that `blockmap replay` reads through.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <string>

#include "blockmap/hal/replay/log_ports.hpp"

namespace blockmap::hal::replay {
namespace {

namespace fs = std::filesystem;

fs::path write_temp(const std::string& name, const std::string& text) {
  fs::path path = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

TEST(CandumpFileBus, GivesTheFramesWithTheirRecordedTimesAndCountsWhatItCannotRead) {
  const fs::path path = write_temp("bus.candump",
                                   "# a comment\n"
                                   "(1156255200.010000) can0 400#0000000000000000\n"
                                   "\n"
                                   "(1156255200.010250) can0 401#000100030003FFFC\n"
                                   "this is not a frame\n"
                                   "(1156255200.020000) can0 123#AB\n"
                                   "(1156255200.030000) can0 402#00010001");  // no final newline
  CandumpFileBus bus(path.string());
  ASSERT_TRUE(bus.ok());
  const std::array<CanFilter, 1> rmp{CanFilter{0x400, 0x7F8}};  // 0x400-0x407
  ASSERT_EQ(bus.set_filters(rmp), IoStatus::kOk);
  CanFrame frame;
  CanReceiveResult r = bus.receive(frame, 0);
  ASSERT_EQ(r.status, IoStatus::kOk);
  EXPECT_EQ(frame.id, 0x400u);
  EXPECT_EQ(r.stamp_ns, 1156255200010000000);
  r = bus.receive(frame, 0);
  ASSERT_EQ(r.status, IoStatus::kOk);
  EXPECT_EQ(frame.id, 0x401u);
  EXPECT_EQ(frame.data[1], 0x01);
  r = bus.receive(frame, 0);  // 0x123 is filtered out
  ASSERT_EQ(r.status, IoStatus::kOk);
  EXPECT_EQ(frame.id, 0x402u);
  EXPECT_EQ(frame.dlc, 4);
  EXPECT_EQ(bus.receive(frame, 0).status, IoStatus::kClosed);
  EXPECT_EQ(bus.lines_rejected(), 1u);
  EXPECT_EQ(bus.first_rejected_line(), 5u);
  EXPECT_EQ(bus.send(frame), IoStatus::kInvalidArgument);
  fs::remove(path);
}

TEST(CandumpFileBus, AMissingLogSaysWhichAndWhy) {
  CandumpFileBus bus("/no/such/rmp.candump");
  EXPECT_FALSE(bus.ok());
  EXPECT_NE(bus.error().find("/no/such/rmp.candump"), std::string::npos);
  CanFrame frame;
  EXPECT_EQ(bus.receive(frame, 0).status, IoStatus::kClosed);
}

TEST(FileByteStream, ReadsTheFileInPiecesThenCloses) {
  std::string text;
  for (int i = 0; i < 100; ++i) {
    text += "$GPGGA,140000.25,3222.48338,N,08448.06342,W,1,10,0.9,141.3,M,-30.0,M,,*5B\r\n";
  }
  const fs::path path = write_temp("gps.nmea", text);
  FileByteStream stream(path.string());
  ASSERT_TRUE(stream.ok());
  std::array<std::uint8_t, 512> buffer{};
  std::string back;
  for (;;) {
    const ReadResult r = stream.read(buffer, 0);
    if (r.status != IoStatus::kOk) {
      EXPECT_EQ(r.status, IoStatus::kClosed);
      break;
    }
    EXPECT_LE(r.bytes, buffer.size());
    back.append(reinterpret_cast<const char*>(buffer.data()), r.bytes);
  }
  EXPECT_EQ(back, text);
  const std::array<std::uint8_t, 1> byte{0};
  EXPECT_EQ(stream.write(byte, 0).status, IoStatus::kInvalidArgument);
  fs::remove(path);
}

}  // namespace
}  // namespace blockmap::hal::replay
