// The mapper's queued scans: two bytes a beam, the ranges given back bit for bit where the
// device measures in millimetres or centimetres.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "blockmap/map/scan_projector.hpp"
#include "blockmap/pipeline/compact_scan.hpp"

namespace blockmap::pipeline {
namespace {

// A scan as the LMS2xx decoder makes it: float(code * unit) in double.
msg::LaserScan lms_scan(double unit_m, std::size_t beams) {
  msg::LaserScan scan;
  scan.header.stamp_ns = 1'000'000'000;
  scan.header.source_id = 7;
  scan.start_angle_rad = -1.5;
  scan.angle_increment_rad = 0.0087;
  scan.time_increment_s = 1.0 / 75.0 / 480.0;
  scan.scan_period_s = 1.0 / 75.0;
  scan.range_min_m = 0.0;
  scan.range_max_m = 81.91;
  scan.scan_counter = 42;
  scan.beam_count = static_cast<std::uint16_t>(beams);
  for (std::size_t i = 0; i < beams; ++i) {
    const auto code = static_cast<double>((i * 7919) % 8191);
    scan.ranges_m[i] = static_cast<float>(code * unit_m);
    scan.status[i] = msg::BeamStatus::kValid;
  }
  scan.status[3] = msg::BeamStatus::kNoReturn;
  scan.ranges_m[3] = 0.0f;
  scan.status[5] = msg::BeamStatus::kDazzled;
  scan.ranges_m[5] = 0.0f;
  scan.status[9] = msg::BeamStatus::kTooClose;
  scan.ranges_m[9] = 0.0f;
  return scan;
}

void expect_same(const msg::LaserScan& a, const msg::LaserScan& b) {
  EXPECT_EQ(a.header.stamp_ns, b.header.stamp_ns);
  EXPECT_EQ(a.header.source_id, b.header.source_id);
  EXPECT_EQ(a.start_angle_rad, b.start_angle_rad);
  EXPECT_EQ(a.angle_increment_rad, b.angle_increment_rad);
  EXPECT_EQ(a.time_increment_s, b.time_increment_s);
  EXPECT_EQ(a.scan_period_s, b.scan_period_s);
  EXPECT_EQ(a.range_max_m, b.range_max_m);
  EXPECT_EQ(a.scan_counter, b.scan_counter);
  ASSERT_EQ(a.beam_count, b.beam_count);
  for (std::size_t i = 0; i < a.beam_count; ++i) {
    EXPECT_EQ(a.status[i], b.status[i]) << i;
    EXPECT_EQ(a.ranges_m[i], b.ranges_m[i]) << i;  // bit for bit
  }
}

TEST(CompactScan, CentimetresAndMillimetresComeBackBitForBit) {
  for (const double unit_m : {0.01, 0.001}) {
    const msg::LaserScan scan = lms_scan(unit_m, 401);
    std::vector<std::uint16_t> codes(401);
    CompactScanHeader header;
    ASSERT_TRUE(compact_scan(scan, header, codes));
    EXPECT_EQ(header.rounded_beams, 0u);
    EXPECT_EQ(header.last_beam_ns, map::ScanProjector::last_beam_stamp_ns(scan));
    EXPECT_GT(header.last_beam_ns, scan.header.stamp_ns);
    msg::LaserScan back;
    back.ranges_m.fill(-1.0f);
    expand_scan(header, codes, back);
    expect_same(scan, back);
  }
}

TEST(CompactScan, RangesNoUnitGivesBackAreRoundedToTheMillimetre) {
  msg::LaserScan scan = lms_scan(0.001, 20);
  scan.ranges_m[0] = 12.3456789f;  // a TiM's scaled value
  std::vector<std::uint16_t> codes(20);
  CompactScanHeader header;
  ASSERT_TRUE(compact_scan(scan, header, codes));
  EXPECT_EQ(header.rounded_beams, 1u);
  msg::LaserScan back;
  expand_scan(header, codes, back);
  EXPECT_NEAR(back.ranges_m[0], 12.3456789f, 0.0005f);
  EXPECT_EQ(back.ranges_m[1], scan.ranges_m[1]);
}

TEST(CompactScan, AScanWiderThanTheSlotIsRefusedAndABadRangeIsAnError) {
  msg::LaserScan scan = lms_scan(0.01, 30);
  std::vector<std::uint16_t> codes(29);
  CompactScanHeader header;
  EXPECT_FALSE(compact_scan(scan, header, codes));
  codes.resize(30);
  scan.ranges_m[1] = std::nanf("");
  ASSERT_TRUE(compact_scan(scan, header, codes));
  msg::LaserScan back;
  expand_scan(header, codes, back);
  EXPECT_EQ(back.status[1], msg::BeamStatus::kDeviceError);
  EXPECT_EQ(back.status[3], msg::BeamStatus::kNoReturn);
}

}  // namespace
}  // namespace blockmap::pipeline
