// GPS fixes as the localizer takes them: NMEA's UTC of day on the run's clock, the geodetic
// position in the local ENU frame (anchored at a configured origin or the first good fix),
// and what the receiver corrected it with (GGA's quality). Shared by `run` and `replay`
// and by the simulated robot.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/localize/particle_filter.hpp"
#include "blockmap/msg/gps_fix.hpp"

namespace blockmap::hal {

// The fix's UTC on the log's clock. With a date (RMC), exact; without one (GGA alone), the day
// that puts it nearest to `near_ns` (the odometry's time), which survives midnight.
[[nodiscard]] TimestampNs fix_stamp_ns(const msg::GpsFix& fix, TimestampNs near_ns);

// What GGA's quality says the fix was corrected with: DGPS, RTK float or fixed, or nothing.
[[nodiscard]] localize::GpsCorrection correction_of(msg::GpsFixQuality quality);

// The fix's ellipsoidal position (NMEA gives the height above the geoid and its separation).
[[nodiscard]] GeodeticPoint fix_point(const msg::GpsFix& fix);

// Which clock a fix's stamp is on.
enum class FixTime : std::uint8_t {
  // The run's clock is UTC (simulated runs, recorded logs): the fix's own UTC.
  kUtc,
  // The receive stamps' clock (CLOCK_MONOTONIC on the robot), which UTC is not on: the fix's
  // UTC moved by the smallest delay from UTC to receipt among the last kDelayWindow fixes.
  // The smallest is the one least held up by the serial line and the reader; a window rather
  // than all time, so that the two clocks' drift (a few ms an hour) is followed.
  kReceiveClock,
};

class FixConverter {
 public:
  static constexpr std::size_t kDelayWindow = 32;

  explicit FixConverter(FixTime time = FixTime::kUtc) : time_(time) {}
  explicit FixConverter(const GeodeticPoint& origin, FixTime time = FixTime::kUtc)
      : frame_(origin), time_(time) {}

  // A usable fix (valid, with position and time) becomes an observation and its height in
  // the local frame; false (counted) otherwise.
  bool convert(const msg::GpsFix& fix, TimestampNs near_ns, localize::GpsObservation& out,
               double& up_m);
  [[nodiscard]] const std::optional<LocalEnuFrame>& frame() const noexcept { return frame_; }
  [[nodiscard]] std::size_t without_position() const noexcept { return without_position_; }
  // kReceiveClock: the delay from UTC to the receive clock in use (receive clock - UTC), ns.
  [[nodiscard]] TimestampNs receive_delay_ns() const noexcept { return best_delay_ns_; }
  // kReceiveClock: how far before its receipt a fix may be stamped, the spread of the window's
  // delays (the most delayed less the least; 0 on kUtc). A merge of the devices' streams by
  // their receive stamps must hold the others back by this much: a fix read late lands that
  // far back, behind messages already handed on (the mapper would drop it as late).
  [[nodiscard]] TimestampNs backdating_ns() const noexcept {
    return worst_delay_ns_ - best_delay_ns_;
  }
  // kReceiveClock: how often the delays started over (the receiver's clock jumped).
  [[nodiscard]] std::size_t clock_restarts() const noexcept { return clock_restarts_; }

  // kReceiveClock: the receiver's pulse-per-second, an edge at the start of each UTC second,
  // stamped on the receive clock by the kernel (a GPIO interrupt). A fix then lands on the
  // edge of its second plus its fraction: exact, where the least delay is late by the serial
  // line's least latency. The edge is the one that puts the fix within kPpsAgreementNs of the
  // least-delay estimate (which settles whose second an edge starts) and not after its receipt;
  // without one (no PPS wired, pulses lost) the estimate stands.
  static constexpr std::size_t kPpsEdges = 4;
  static constexpr TimestampNs kPpsAgreementNs = 400'000'000;
  void on_pps(TimestampNs edge_ns) noexcept;
  [[nodiscard]] std::size_t pps_fixes() const noexcept { return pps_fixes_; }

 private:
  // The fix's stamp on the receive clock, learning the delay (kReceiveClock).
  [[nodiscard]] TimestampNs on_receive_clock(const msg::GpsFix& fix);
  // `estimate_ns` moved onto a PPS edge when one agrees (see on_pps).
  [[nodiscard]] TimestampNs on_pps_edge(TimestampNs utc_ns, TimestampNs estimate_ns,
                                        TimestampNs received_ns);

  std::optional<LocalEnuFrame> frame_;
  FixTime time_ = FixTime::kUtc;
  std::size_t without_position_ = 0;
  std::array<TimestampNs, kDelayWindow> delays_ns_{};
  std::size_t delay_count_ = 0;  // delays seen since the last restart
  TimestampNs best_delay_ns_ = 0;
  TimestampNs worst_delay_ns_ = 0;
  std::size_t clock_restarts_ = 0;
  std::array<TimestampNs, kPpsEdges> pps_edges_ns_{};
  std::size_t pps_count_ = 0;
  std::size_t pps_fixes_ = 0;
};

}  // namespace blockmap::hal
