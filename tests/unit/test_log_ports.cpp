// The ports over recorded logs that `blockmap replay` reads through.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

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

TEST(RecordedTimes, ATimeOffBothNeighboursTakesTheLastGoodOne) {
  RecordedTimes times;
  constexpr TimestampNs kMs = 1'000'000;
  const std::array<TimestampNs, 3> after = {30 * kMs, 40 * kMs, 50 * kMs};
  EXPECT_EQ(times.judge(10 * kMs, std::span(after).first(3)), 10 * kMs);
  // A digit of the second one's time damaged: 1e8 s ahead, the next ones where they were.
  EXPECT_EQ(times.judge(100'000'000 * kNanosecondsPerSecond, std::span(after)), 10 * kMs);
  EXPECT_EQ(times.judge(30 * kMs, std::span(after).subspan(1)), 30 * kMs);
  EXPECT_EQ(times.faults(), 1u);
  EXPECT_EQ(times.steps(), 0u);
}

TEST(RecordedTimes, AJumpTheNextRecordsKeepIsTheClocksStep) {
  RecordedTimes times;
  constexpr TimestampNs kS = kNanosecondsPerSecond;
  const std::array<TimestampNs, 3> kept = {100 * kS + 10'000'000, 100 * kS + 20'000'000,
                                           100 * kS + 30'000'000};
  EXPECT_EQ(times.judge(1 * kS, {}), 1 * kS);
  EXPECT_EQ(times.judge(100 * kS, std::span(kept)), 100 * kS);
  EXPECT_EQ(times.steps(), 1u);
  EXPECT_EQ(times.faults(), 0u);
  // Backwards too, and the end of the log cannot confirm a jump.
  EXPECT_EQ(times.judge(2 * kS, {}), 100 * kS);
  EXPECT_EQ(times.faults(), 1u);
}

TEST(RecordedTimes, ATimeALittleBackWhoseSuccessorsKeepTheOldClockIsAFault) {
  RecordedTimes times;
  constexpr TimestampNs kMs = 1'000'000;
  EXPECT_EQ(times.judge(1000 * kMs, {}), 1000 * kMs);
  // 0.1 s back: the next ones follow it, but they follow the last good time too.
  const std::array<TimestampNs, 3> after = {1020 * kMs, 1030 * kMs, 1040 * kMs};
  EXPECT_EQ(times.judge(910 * kMs, std::span(after)), 1000 * kMs);
  EXPECT_EQ(times.faults(), 1u);
  EXPECT_EQ(times.steps(), 0u);
}

TEST(RecordedTimes, AFirstRecordItsSuccessorsDoNotFollowIsDropped) {
  RecordedTimes times;
  constexpr TimestampNs kMs = 1'000'000;
  const std::array<TimestampNs, 3> after = {20 * kMs, 30 * kMs, 40 * kMs};
  EXPECT_EQ(times.judge(9'000'000 * kMs, std::span(after)), std::nullopt);
  EXPECT_EQ(times.judge(10 * kMs, std::span(after)), 10 * kMs);
  EXPECT_EQ(times.faults(), 1u);
}

TEST(CandumpFileBus, AFrameWhoseTimeADamagedDigitMovedKeepsItsPlace) {
  const fs::path path = write_temp("jump.candump",
                                   "(1156255200.010000) can0 400#01\n"
                                   "(1156255200.020000) can0 400#02\n"
                                   "(1256255200.030000) can0 400#03\n"  // a 1 for a 2
                                   "(1156255200.040000) can0 400#04\n"
                                   "(1156255200.050000) can0 400#05\n");
  CandumpFileBus bus(path.string());
  std::vector<TimestampNs> stamps;
  CanFrame frame;
  for (CanReceiveResult r = bus.receive(frame, 0); r.status == IoStatus::kOk;
       r = bus.receive(frame, 0)) {
    stamps.push_back(r.stamp_ns);
  }
  EXPECT_EQ(stamps,
            (std::vector<TimestampNs>{1156255200010000000, 1156255200020000000, 1156255200020000000,
                                      1156255200040000000, 1156255200050000000}));
  EXPECT_EQ(bus.times().faults(), 1u);
  fs::remove(path);
}

// A byte log of `count` device records, 10 ms apart, each of `bytes` bytes of its index.
std::string byte_log(int count, std::size_t bytes) {
  std::string log(protocol::byte_log::kMagic.begin(), protocol::byte_log::kMagic.end());
  for (int i = 0; i < count; ++i) {
    std::array<std::uint8_t, protocol::byte_log::kRecordHeaderBytes> header{};
    protocol::byte_log::encode_record_header(
        {1'000'000'000 + i * 10'000'000, static_cast<std::uint32_t>(bytes),
         protocol::byte_log::Direction::kFromDevice},
        header);
    log.append(header.begin(), header.end());
    log.append(bytes, static_cast<char>('a' + i));
  }
  return log;
}

std::string read_all(ByteLogFileStream& stream) {
  std::string text;
  std::array<std::uint8_t, 64> buffer{};
  for (ReadResult r = stream.read(buffer, 0); r.status == IoStatus::kOk;
       r = stream.read(buffer, 0)) {
    text.append(buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(r.bytes));
  }
  return text;
}

TEST(ByteLogFileStream, ADamagedRecordIsSkippedAndTheRestRead) {
  std::string log = byte_log(6, 20);
  constexpr std::size_t kRecord = protocol::byte_log::kRecordHeaderBytes + 20;
  log[8 + 2 * kRecord + 13] = 4;  // the third record's reserved byte
  const fs::path path = write_temp("damaged.bytelog", log);
  ByteLogFileStream stream(path.string());
  ASSERT_TRUE(stream.ok()) << stream.error();
  const std::string text = read_all(stream);
  EXPECT_EQ(text, std::string(20, 'a') + std::string(20, 'b') + std::string(20, 'd') +
                      std::string(20, 'e') + std::string(20, 'f'));
  EXPECT_EQ(stream.skipped_places(), 1u);
  EXPECT_EQ(stream.skipped_bytes(), kRecord);
  EXPECT_EQ(stream.first_skip_offset(), 8 + 2 * kRecord);
  EXPECT_EQ(stream.first_skip(), protocol::byte_log::ParseError::kBadReserved);
  EXPECT_EQ(stream.damage(), protocol::byte_log::ParseError::kNone);
  fs::remove(path);
}

TEST(ByteLogFileStream, ALengthADamagedBitChangedIsNotBelieved) {
  std::string log = byte_log(6, 20);
  constexpr std::size_t kRecord = protocol::byte_log::kRecordHeaderBytes + 20;
  log[8 + kRecord + 8] = 21;  // the second record says 21 bytes
  const fs::path path = write_temp("length.bytelog", log);
  ByteLogFileStream stream(path.string());
  const std::string text = read_all(stream);
  EXPECT_EQ(text, std::string(20, 'a') + std::string(20, 'c') + std::string(20, 'd') +
                      std::string(20, 'e') + std::string(20, 'f'));
  EXPECT_EQ(stream.skipped_places(), 1u);
  fs::remove(path);
}

TEST(ByteLogFileStream, ALengthDamagedOntoALaterRecordIsNotBelieved) {
  constexpr int kRecords = 40;
  std::string log = byte_log(kRecords, 20);
  constexpr std::size_t kRecord = protocol::byte_log::kRecordHeaderBytes + 20;
  // The second record says it runs to the 33rd's header: a header that reads well, 0.31 s on.
  std::array<std::uint8_t, protocol::byte_log::kRecordHeaderBytes> header{};
  protocol::byte_log::encode_record_header(
      {1'010'000'000, 20 + 31 * kRecord, protocol::byte_log::Direction::kFromDevice}, header);
  std::copy(header.begin(), header.end(), log.begin() + 8 + kRecord);
  const fs::path path = write_temp("landing.bytelog", log);
  ByteLogFileStream stream(path.string());
  std::string expected(20, 'a');
  for (int i = 2; i < kRecords; ++i) {
    expected.append(20, static_cast<char>('a' + i));
  }
  EXPECT_EQ(read_all(stream), expected);
  EXPECT_EQ(stream.skipped_places(), 1u);
  EXPECT_EQ(stream.first_skip(), protocol::byte_log::ParseError::kBadLength);
  fs::remove(path);
}

TEST(ByteLogFileStream, ADamagedMagicBeforeRecordsThatReadWellLosesNothingElse) {
  std::string log = byte_log(3, 20);
  log[2] = static_cast<char>(log[2] ^ 0x08);
  const fs::path path = write_temp("magic.bytelog", log);
  ByteLogFileStream stream(path.string());
  ASSERT_TRUE(stream.ok()) << stream.error();
  EXPECT_EQ(read_all(stream), std::string(20, 'a') + std::string(20, 'b') + std::string(20, 'c'));
  EXPECT_EQ(stream.skipped_places(), 1u);
  EXPECT_EQ(stream.skipped_bytes(), 8u);
  EXPECT_EQ(stream.first_skip(), protocol::byte_log::ParseError::kBadMagic);
  fs::remove(path);
  // Text is not a byte log, whatever its first bytes.
  const fs::path text = write_temp("text.bytelog", "(1156255200.010000) can0 400#01\n");
  EXPECT_FALSE(ByteLogFileStream(text.string()).ok());
  fs::remove(text);
}

TEST(ByteLogFileStream, ADamagedLastRecordIsOneMorePlaceSkipped) {
  std::string log = byte_log(3, 20);
  constexpr std::size_t kRecord = protocol::byte_log::kRecordHeaderBytes + 20;
  log[8 + 2 * kRecord + 14] = 0x40;  // a reserved byte of the last header
  const fs::path path = write_temp("last.bytelog", log);
  ByteLogFileStream stream(path.string());
  EXPECT_EQ(read_all(stream), std::string(20, 'a') + std::string(20, 'b'));
  EXPECT_EQ(stream.damage(), protocol::byte_log::ParseError::kNone);
  EXPECT_EQ(stream.skipped_places(), 1u);
  EXPECT_EQ(stream.skipped_bytes(), kRecord);
  fs::remove(path);
}

TEST(ByteLogFileStream, ALogCutInARecordEndsDamagedThere) {
  std::string log = byte_log(4, 20);
  log.resize(log.size() - 5);
  const fs::path path = write_temp("cut.bytelog", log);
  ByteLogFileStream stream(path.string());
  EXPECT_EQ(read_all(stream), std::string(20, 'a') + std::string(20, 'b') + std::string(20, 'c'));
  EXPECT_EQ(stream.damage(), protocol::byte_log::ParseError::kTruncatedData);
  EXPECT_EQ(stream.damage_offset(), 8 + 3 * (protocol::byte_log::kRecordHeaderBytes + 20));
  fs::remove(path);
}

}  // namespace
}  // namespace blockmap::hal::replay
