// The simulated devices inside a Simulation (private to hal/sim): each knows when its next
// output is due and produces it through the device's real encoder.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "blockmap/hal/geodesy.hpp"
#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "blockmap/hal/sim/random.hpp"
#include "blockmap/hal/sim/sensor_models.hpp"
#include "blockmap/hal/sim/serial_wire.hpp"
#include "blockmap/hal/sim/simulation.hpp"

namespace blockmap::hal::sim::detail {

inline constexpr TimestampNs kNever = SerialWire::kNever;

// What every device model reads: the world, the robot's motion and the clock's origin.
struct SimContext {
  Scene& scene;
  RobotMotion& motion;
  TimestampNs start_ns = 0;
  TimestampNs end_ns = kNever;  // no new cycles, scans or epochs start after this

  [[nodiscard]] double seconds(TimestampNs stamp_ns) const {
    return static_cast<double>(stamp_ns - start_ns) * 1e-9;
  }
  [[nodiscard]] TimestampNs stamp(double t_s) const {
    return start_ns + static_cast<TimestampNs>(std::llround(t_s * 1e9));
  }
};

// The Segway RMP: a status group of eight frames every 10 ms, 250 us apart on the bus.
class SimRmp {
 public:
  SimRmp(const config::BaseSpec& base, std::uint64_t seed);
  [[nodiscard]] TimestampNs next_event_ns(const SimContext& context) const noexcept;
  void fire(SimContext& context, SimSink& sink, SimStats& stats);

 private:
  void make_cycle(SimContext& context, SimSink& sink, TimestampNs cycle_ns);

  config::BaseSpec base_;
  BaseSensing sensing_;
  protocol::segway_rmp::Config codec_;
  SimRandom random_;
  std::uint64_t cycle_ = 0;
  protocol::segway_rmp::StatusFrames frames_{};
  TimestampNs frames_ns_ = 0;
  std::size_t next_frame_ = 8;  // 8: none pending
};

// A SICK LMS2xx in continuous mode on its serial line.
class SimLms {
 public:
  SimLms(const config::LaserSpec& spec, std::size_t device, std::uint64_t seed);
  [[nodiscard]] TimestampNs next_event_ns(const SimContext& context) const noexcept;
  void fire(SimContext& context, SimSink& sink, SimStats& stats);
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  [[nodiscard]] TimestampNs scan_start_ns(const SimContext& context, std::uint64_t scan) const;
  [[nodiscard]] TimestampNs scan_ready_ns(const SimContext& context, std::uint64_t scan) const;
  // From a scan's first beam to its last.
  [[nodiscard]] double scan_span_s() const noexcept;
  void start_handshake(const SimContext& context, SimSink& sink);
  void measure_scan(SimContext& context, SimSink& sink, SimStats& stats);

  config::LaserSpec spec_;
  std::size_t device_;
  SimRandom random_;
  SerialWire wire_;
  protocol::sick_lms2xx::VariantGeometry geometry_{};
  int turns_per_scan_ = 1;
  std::uint64_t turns_between_scans_ = 1;
  double first_turn_s_ = 0.0;
  double range_max_m_ = 80.0;
  bool started_ = false;
  std::uint64_t next_scan_ = 0;
  std::array<Vec3, 401> beam_directions_{};  // in the sensor frame, by beam
  std::array<std::uint16_t, 401> values_{};
  std::array<std::uint8_t, protocol::sick_lms2xx::kMaxTelegramBytes> telegram_{};
};

// An NMEA GPS receiver: an epoch every 1 / rate s, GGA + RMC + GSA a little later.
class SimGps {
 public:
  SimGps(const config::GpsSpec& spec, const Site& site, std::size_t device, std::uint64_t seed);
  [[nodiscard]] TimestampNs next_event_ns(const SimContext& context) const noexcept;
  void fire(SimContext& context, SimSink& sink, SimStats& stats);
  // Epochs in [from_ns, to_ns) are computed but not sent.
  void set_silence(TimestampNs from_ns, TimestampNs to_ns) noexcept {
    silent_from_ns_ = from_ns;
    silent_to_ns_ = to_ns;
  }
  // This share of the fixes is off by `jump_m` in a random direction (a reflected signal
  // taken for the direct one), drawn apart from the rest of the run's randomness.
  void set_jumps(double fraction, double jump_m) noexcept {
    jump_fraction_ = fraction;
    jump_m_ = jump_m;
  }
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return wire_.memory_bytes(); }

 private:
  struct Satellite {
    double azimuth_rad = 0.0;  // clockwise from north
    double elevation_rad = 0.0;
    std::uint16_t id = 0;
  };
  [[nodiscard]] TimestampNs epoch_ns(const SimContext& context, std::uint64_t epoch) const;
  void make_epoch(SimContext& context, SimSink& sink, SimStats& stats);
  [[nodiscard]] bool blocked(const SimContext& context, const Vec3& antenna,
                             const Satellite& satellite) const;

  config::GpsSpec spec_;
  Site site_;
  LocalEnuFrame frame_;
  std::size_t device_;
  SimRandom random_;
  SimRandom jumps_random_;  // apart, so that the jumps leave the rest of the run as it was
  SerialWire wire_;
  std::vector<Satellite> satellites_;
  GpsErrorProcess error_;
  std::uint64_t next_epoch_ = 1;
  TimestampNs silent_from_ns_ = 0;
  TimestampNs silent_to_ns_ = 0;
  double jump_fraction_ = 0.0;
  double jump_m_ = 0.0;
  std::array<char, protocol::nmea::kMaxSentenceBytes> sentence_{};
};

}  // namespace blockmap::hal::sim::detail
