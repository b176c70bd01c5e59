#include "blockmap/pipeline/compact_scan.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "blockmap/map/scan_projector.hpp"

namespace blockmap::pipeline {
namespace {

// The units tried, finest first: the decoders compute a range as float(code * unit) in
// double, so a code in the device's own unit gives the range back bit for bit.
constexpr std::array<double, 2> kUnitsM{0.001, 0.01};

float range_of(std::uint16_t code, double unit_m) noexcept {
  return static_cast<float>(static_cast<double>(code) * unit_m);
}

bool valid(const msg::LaserScan& scan, std::size_t i) noexcept {
  return scan.status[i] == msg::BeamStatus::kValid && std::isfinite(scan.ranges_m[i]) &&
         scan.ranges_m[i] >= 0.0f;
}

long code_of(float range_m, double unit_m) noexcept {
  return std::lround(static_cast<double>(range_m) / unit_m);
}

// The first unit that gives every valid range back exactly, else the finest in which they
// all fit under kInvalidCode.
double unit_for(const msg::LaserScan& scan) noexcept {
  double fitting_m = 0.0;
  for (const double unit_m : kUnitsM) {
    bool fits = true;
    bool exact = true;
    for (std::size_t i = 0; i < scan.beam_count && fits; ++i) {
      if (!valid(scan, i)) {
        continue;
      }
      const long code = code_of(scan.ranges_m[i], unit_m);
      fits = code < kInvalidCode;
      exact = exact && range_of(static_cast<std::uint16_t>(code), unit_m) == scan.ranges_m[i];
    }
    if (fits && exact) {
      return unit_m;
    }
    if (fits && fitting_m == 0.0) {
      fitting_m = unit_m;
    }
  }
  return fitting_m > 0.0 ? fitting_m : 1.0;  // 65 km: beyond any of these lasers
}

}  // namespace

bool compact_scan(const msg::LaserScan& scan, CompactScanHeader& header,
                  std::span<std::uint16_t> codes) noexcept {
  if (scan.beam_count > codes.size()) {
    return false;
  }
  header.header = scan.header;
  header.last_beam_ns = map::ScanProjector::last_beam_stamp_ns(scan);
  header.start_angle_rad = scan.start_angle_rad;
  header.angle_increment_rad = scan.angle_increment_rad;
  header.time_increment_s = scan.time_increment_s;
  header.scan_period_s = scan.scan_period_s;
  header.range_min_m = scan.range_min_m;
  header.range_max_m = scan.range_max_m;
  header.scan_counter = scan.scan_counter;
  header.beam_count = scan.beam_count;
  header.unit_m = unit_for(scan);
  header.rounded_beams = 0;
  for (std::size_t i = 0; i < scan.beam_count; ++i) {
    if (!valid(scan, i)) {
      const msg::BeamStatus status = scan.status[i] == msg::BeamStatus::kValid
                                         ? msg::BeamStatus::kDeviceError
                                         : scan.status[i];
      codes[i] = static_cast<std::uint16_t>(kInvalidCode + static_cast<std::uint16_t>(status));
      continue;
    }
    const auto code = static_cast<std::uint16_t>(
        std::min<long>(code_of(scan.ranges_m[i], header.unit_m), kInvalidCode - 1));
    if (range_of(code, header.unit_m) != scan.ranges_m[i]) {
      ++header.rounded_beams;
    }
    codes[i] = code;
  }
  return true;
}

void expand_scan(const CompactScanHeader& header, std::span<const std::uint16_t> codes,
                 msg::LaserScan& out) noexcept {
  out.header = header.header;
  out.start_angle_rad = header.start_angle_rad;
  out.angle_increment_rad = header.angle_increment_rad;
  out.time_increment_s = header.time_increment_s;
  out.scan_period_s = header.scan_period_s;
  out.range_min_m = header.range_min_m;
  out.range_max_m = header.range_max_m;
  out.scan_counter = header.scan_counter;
  out.beam_count = header.beam_count;
  out.has_intensities = false;
  for (std::size_t i = 0; i < header.beam_count; ++i) {
    const std::uint16_t code = codes[i];
    if (code >= kInvalidCode) {
      out.status[i] = static_cast<msg::BeamStatus>(code - kInvalidCode);
      out.ranges_m[i] = 0.0f;
    } else {
      out.status[i] = msg::BeamStatus::kValid;
      out.ranges_m[i] = range_of(code, header.unit_m);
    }
  }
}

}  // namespace blockmap::pipeline
