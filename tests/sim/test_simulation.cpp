// A whole simulated run: its bytes decode back to what was simulated, its truth agrees with its
// laser returns, the Segway pitches with its acceleration, the GPS errs as configured, and a
// seed always gives the same bytes.
#include "blockmap/hal/sim/simulation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <memory>
#include <numbers>
#include <vector>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/geodesy.hpp"
#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/protocol/segway_rmp.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "blockmap/hal/sim/sim_ports.hpp"

namespace blockmap::hal::sim {
namespace {

namespace lms = protocol::sick_lms2xx;
namespace rmp = protocol::segway_rmp;
namespace nmea = protocol::nmea;

SimOptions options_for(double seconds, std::uint64_t seed = 1) {
  SimOptions options;
  options.seed = seed;
  options.max_duration_s = seconds;
  return options;
}

// FNV-1a over every byte and stamp a run hands out.
class HashingSink final : public SimSink {
 public:
  void on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) override {
    add(stamp_ns);
    add(frame.id);
    for (std::size_t i = 0; i < frame.dlc; ++i) {
      add(frame.data[i]);
    }
  }
  void on_serial(std::size_t device, TimestampNs stamp_ns,
                 protocol::byte_log::Direction /*direction*/,
                 std::span<const std::uint8_t> bytes) override {
    add(device);
    add(stamp_ns);
    for (const std::uint8_t byte : bytes) {
      add(byte);
    }
    bytes_ += bytes.size();
  }
  std::uint64_t hash = 1469598103934665603ULL;
  std::uint64_t bytes_ = 0;

 private:
  template <typename Integer>
  void add(Integer value) {
    hash = (hash ^ static_cast<std::uint64_t>(value)) * 1099511628211ULL;
  }
};

TEST(Simulation, TheSameSeedGivesTheSameBytesAndAnotherSeedOthers) {
  const World world = load_world("usc_block");
  const config::RobotSpec robot = config::load_robot("paper_rmp");
  HashingSink first;
  HashingSink again;
  HashingSink other;
  Simulation(world, robot, options_for(3.0, 5)).run(first);
  Simulation(world, robot, options_for(3.0, 5)).run(again);
  Simulation(world, robot, options_for(3.0, 6)).run(other);
  EXPECT_GT(first.bytes_, 100'000u);
  EXPECT_EQ(first.hash, again.hash);
  EXPECT_NE(first.hash, other.hash);
}

// Decodes everything a run sends, as the robot would, and keeps the truth beside it.
class DecodingSink final : public SimSink {
 public:
  explicit DecodingSink(const Simulation& simulation)
      : frame_(simulation.world().site.origin),
        gps_quality_(simulation.robot().gps.fix_quality),
        rmp_(rmp_config(simulation.robot())),
        lasers_(simulation.robot().lasers.size()) {
    for (Laser& laser : lasers_) {
      laser.decoder = std::make_unique<lms::Decoder>();
    }
  }

  void on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) override {
    const rmp::Decoder::Step step = rmp_.push(frame, stamp_ns);
    if (step.cycle != nullptr) {
      ASSERT_FALSE(states_.empty());
      const RobotState& truth = states_.back();
      const msg::ImuSample& imu = step.cycle->imu;
      // The IMU's noise (0.2 deg, 0.6 deg/s) at five sigma, plus the counts' resolution.
      EXPECT_NEAR(imu.pitch_rad, truth.pitch_rad, 5 * 0.0035 + 0.003);
      EXPECT_NEAR(imu.roll_rad, truth.roll_rad, 5 * 0.0035 + 0.003);
      EXPECT_NEAR(imu.yaw_rate_radps, truth.yaw_rate_radps + 0.3 * std::numbers::pi / 180,
                  5 * 0.0105 + 0.003);
      // Wheels: the true travel times the tyre-pressure scale, plus accumulated slip.
      EXPECT_NEAR(step.cycle->odometry.left_wheel_distance_m, truth.left_wheel_m * 1.012, 0.01);
      EXPECT_NEAR(step.cycle->odometry.right_wheel_distance_m, truth.right_wheel_m * 0.994, 0.01);
      ++cycles;
    }
  }

  void on_truth_state(TimestampNs /*stamp_ns*/, const RobotState& state) override {
    states_.push_back(state);
  }

  void on_beam(std::size_t laser, const BeamTruth& beam) override {
    lasers_[laser].pending.push_back(beam.returned ? beam.measured_range_m : -1.0);
  }

  void on_gps_epoch(const GpsTruth& truth) override { gps_truth_.push_back(truth); }

  void on_serial(std::size_t device, TimestampNs stamp_ns, protocol::byte_log::Direction direction,
                 std::span<const std::uint8_t> bytes) override {
    if (direction == protocol::byte_log::Direction::kToDevice) {
      return;
    }
    if (device < lasers_.size()) {
      decode_laser(lasers_[device], bytes, stamp_ns);
    } else {
      decode_gps(bytes, stamp_ns);
    }
  }

  int cycles = 0;
  int scans = 0;
  int fixes = 0;

 private:
  static rmp::Config rmp_config(const config::RobotSpec& robot) {
    rmp::Config config;
    config.model = robot.base.model;
    config.yaw_sign = robot.base.yaw_sign;
    return config;
  }

  struct Laser {
    std::unique_ptr<lms::Decoder> decoder;
    std::deque<double> pending;  // measured ranges of the beams sent, in order
  };

  void decode_laser(Laser& laser, std::span<const std::uint8_t> bytes, TimestampNs stamp_ns) {
    for (;;) {
      const lms::Decoder::Step step = laser.decoder->push(bytes, stamp_ns);
      bytes = bytes.subspan(step.consumed);
      if (step.event == lms::Decoder::Event::kNone) {
        break;
      }
      ASSERT_NE(step.event, lms::Decoder::Event::kRejected);
      if (step.event != lms::Decoder::Event::kTelegram || !step.telegram->has_scan) {
        continue;
      }
      const msg::LaserScan& scan = step.telegram->scan;
      ASSERT_GE(laser.pending.size(), scan.beam_count);
      for (std::size_t i = 0; i < scan.beam_count; ++i) {
        const double measured = laser.pending.front();
        laser.pending.pop_front();
        if (measured < 0.0) {
          EXPECT_NE(scan.status[i], msg::BeamStatus::kValid);
        } else {
          ASSERT_EQ(scan.status[i], msg::BeamStatus::kValid) << "beam " << i;
          EXPECT_NEAR(scan.ranges_m[i], measured, 0.005 + 1e-5) << "within the cm units";
        }
      }
      ++scans;
    }
  }

  void decode_gps(std::span<const std::uint8_t> bytes, TimestampNs stamp_ns) {
    while (!bytes.empty()) {
      const nmea::Decoder::Step step = nmea_.push(bytes, stamp_ns);
      bytes = bytes.subspan(step.consumed);
      ASSERT_FALSE(step.rejected);
      if (step.sentence == nullptr || step.sentence->type != nmea::SentenceType::kGga) {
        continue;
      }
      const msg::GpsFix& fix = step.sentence->fix;
      ASSERT_FALSE(gps_truth_.empty());
      const GpsTruth& truth = gps_truth_.front();
      ASSERT_TRUE(fix.has_position);
      const Vec3 enu = frame_.to_enu_m(
          {fix.latitude_deg, fix.longitude_deg, fix.altitude_msl_m + fix.geoid_separation_m});
      const Vec3 expected = truth.antenna_m + truth.error_m;
      EXPECT_EQ(fix.quality, gps_quality_);
      // Five decimals of a minute and one of a metre; an RTK fix seven and three.
      const bool carrier_phase = gps_quality_ == msg::GpsFixQuality::kRtkFixed;
      const double horizontal_m = carrier_phase ? 0.001 : 0.02;
      EXPECT_NEAR(enu.x(), expected.x(), horizontal_m);
      EXPECT_NEAR(enu.y(), expected.y(), horizontal_m);
      EXPECT_NEAR(enu.z(), expected.z(), carrier_phase ? 0.002 : 0.06);
      EXPECT_NEAR(fix.hdop, truth.hdop, 0.05);
      gps_truth_.pop_front();
      ++fixes;
    }
  }

  LocalEnuFrame frame_;
  msg::GpsFixQuality gps_quality_;
  rmp::Decoder rmp_;
  nmea::Decoder nmea_;
  std::vector<Laser> lasers_;
  std::vector<RobotState> states_;
  std::deque<GpsTruth> gps_truth_;
};

TEST(Simulation, ItsBytesDecodeBackToWhatWasSimulated) {
  Simulation simulation(load_world("usc_block"), config::load_robot("paper_rmp"), options_for(8.0));
  DecodingSink sink(simulation);
  simulation.run(sink);
  EXPECT_NEAR(sink.cycles, 800, 2);
  EXPECT_GE(sink.scans, 2 * 8 * 75 - 10);
  EXPECT_GE(sink.fixes, 8 * 4 - 1);
}

// An RTK receiver says so in GGA (quality 4) and writes its centimetre fixes finely enough:
// they decode to within a millimetre of what was simulated.
TEST(Simulation, AnRtkReceiversFixesDecodeToTheMillimetre) {
  Simulation simulation(load_world("usc_block"), config::load_robot("paper_rmp_rtk"),
                        options_for(8.0));
  DecodingSink sink(simulation);
  simulation.run(sink);
  EXPECT_GE(sink.fixes, 8 * 4 - 1);
}

TEST(Simulation, HalfDegreeScansInterlaceTwoMirrorTurnsAndMillimetreUnitsReachEightMetres) {
  config::RobotSpec robot = config::load_robot("paper_rmp");
  robot.lasers[0].variant = lms::AngularVariant::k180DegHalfDeg;
  robot.lasers[0].scan_rate_hz = 37.5;
  robot.lasers[1].units = lms::Units::kMm;  // 13 range bits in mm: 8.191 m at most
  Simulation simulation(load_world("usc_block"), robot, options_for(4.0));
  DecodingSink sink(simulation);
  simulation.run(sink);
  EXPECT_NEAR(static_cast<double>(simulation.stats().scans_sent[0]), 4 * 37.5, 2);
  EXPECT_NEAR(static_cast<double>(simulation.stats().scans_sent[1]), 4 * 75.0, 2);
  EXPECT_GT(sink.scans, 400);  // and every one decoded to its simulated ranges (in the sink)
}

// Every returned beam's point lies on the face it hit.
class FaceCheckingSink final : public SimSink {
 public:
  explicit FaceCheckingSink(const Scene& scene) : scene_(scene), counted_(scene.faces().size()) {}
  void on_beam(std::size_t /*laser*/, const BeamTruth& beam) override {
    if (!beam.returned || beam.hit.face < 0) {
      return;
    }
    const TruthFace& face = scene_.faces()[static_cast<std::size_t>(beam.hit.face)];
    const Vec3 point = beam.origin_m + beam.measured_range_m * beam.direction;
    ++counted_[static_cast<std::size_t>(beam.hit.face)];
    const double noise = 5 * 0.01;
    if (face.kind == SurfaceKind::kGround) {
      const Terrain& terrain = scene_.terrain();
      EXPECT_NEAR(point.z(), terrain.height_m(point.x(), point.y()), noise + 0.01);
      EXPECT_GE(point.z(), terrain.min_height_m() - noise);
      EXPECT_LE(point.z(), terrain.max_height_m() + noise);
      return;
    }
    EXPECT_NEAR(face.normal.dot(point), face.d_m, noise);
    // Within the face's corners: along the wall and between the ground and the roof.
    const Vec3& a = face.corners_m[0];
    const Vec3& b = face.corners_m[1];
    const Vec3 along = (b - a).normalized();
    const double s = (point - a).dot(along);
    EXPECT_GE(s, -noise);
    EXPECT_LE(s, (b - a).norm() + noise);
    EXPECT_LE(point.z(), face.corners_m[2].z() + noise);
    ++checked;
  }
  [[nodiscard]] const std::vector<std::uint64_t>& counted() const { return counted_; }
  std::uint64_t checked = 0;

 private:
  const Scene& scene_;
  std::vector<std::uint64_t> counted_;
};

TEST(Simulation, TruthFacesAgreeWithTheLaserReturnsThatHitThem) {
  Simulation simulation(load_world("usc_block"), config::load_robot("paper_rmp"),
                        options_for(20.0));
  FaceCheckingSink sink(simulation.scene());
  simulation.run(sink);
  EXPECT_GT(sink.checked, 10'000u);
  for (std::size_t i = 0; i < simulation.scene().faces().size(); ++i) {
    EXPECT_EQ(simulation.scene().faces()[i].returns, sink.counted()[i]) << "face " << i;
  }
}

// Records the true state at every RMP cycle.
class StateSink final : public SimSink {
 public:
  void on_truth_state(TimestampNs /*stamp_ns*/, const RobotState& state) override {
    states.push_back(state);
  }
  void on_gps_epoch(const GpsTruth& truth) override { gps.push_back(truth); }
  std::vector<RobotState> states;
  std::vector<GpsTruth> gps;
};

World straight_road(double length_m) {
  World world;
  world.name = "road";
  world.site.origin = {40.0, -80.0, 100.0};
  world.site.start_unix_s = 1.0e9;
  world.path.waypoints_m = {Vec2(0, 0), Vec2(length_m, 0)};
  world.path.cruise_speed_mps = 1.2;
  return world;
}

config::RobotSpec robot_without_lasers() {
  config::RobotSpec robot = config::load_robot("paper_rmp");
  robot.lasers.clear();
  return robot;
}

TEST(Simulation, TheSegwayPitchesWithItsAccelerationAndBraking) {
  const config::RobotSpec robot = robot_without_lasers();
  Simulation simulation(straight_road(30.0), robot, SimOptions{});
  StateSink sink;
  simulation.run(sink);
  ASSERT_TRUE(simulation.motion().finished());
  EXPECT_NEAR(simulation.motion().distance_m(), 30.0, 0.3);
  const double k = robot.base.pitch_per_accel_rad_per_mps2;
  double max_pitch = 0.0;
  double min_pitch = 0.0;
  double cruise_pitch = 0.0;
  for (const RobotState& state : sink.states) {
    max_pitch = std::max(max_pitch, state.pitch_rad);
    min_pitch = std::min(min_pitch, state.pitch_rad);
    if (state.t_s > 8.0 && state.t_s < 20.0) {
      cruise_pitch = std::max(cruise_pitch, std::abs(state.pitch_rad));
    }
  }
  // Leaning forward while it speeds up, back while it brakes, upright in between: several
  // degrees, as the paper says ("it pitches considerably during acceleration and deceleration").
  EXPECT_NEAR(max_pitch, k * robot.base.max_accel_mps2, 0.5 * k * robot.base.max_accel_mps2);
  EXPECT_NEAR(min_pitch, -k * robot.base.max_decel_mps2, 0.5 * k * robot.base.max_decel_mps2);
  EXPECT_GT(max_pitch * 180 / std::numbers::pi, 1.5);
  EXPECT_LT(cruise_pitch, 0.002);
  // And the pitch follows the acceleration: strongly correlated, a fraction of a second late.
  double sxy = 0.0;
  double sxx = 0.0;
  double syy = 0.0;
  for (std::size_t i = 40; i < sink.states.size(); ++i) {
    const double a = sink.states[i - 40].accel_mps2;  // 0.4 s earlier
    const double p = sink.states[i].pitch_rad;
    sxy += a * p;
    sxx += a * a;
    syy += p * p;
  }
  EXPECT_GT(sxy / std::sqrt(sxx * syy), 0.8);
}

TEST(Simulation, BumpsShakeThePitchAndRoughGroundTheRoll) {
  World rough = straight_road(20.0);
  rough.ground.roughness_m = 0.03;
  rough.ground.bumps.push_back({Vec2(10.0, 0.0), 0.3, 0.06});
  Simulation simulation(rough, robot_without_lasers(), SimOptions{});
  StateSink sink;
  simulation.run(sink);
  double pitch_near_bump = 0.0;
  double roll = 0.0;
  for (const RobotState& state : sink.states) {
    if (std::abs(state.position_m.x() - 10.0) < 1.0 && state.speed_mps > 1.0) {
      pitch_near_bump = std::max(pitch_near_bump, std::abs(state.pitch_rad));
    }
    roll = std::max(roll, std::abs(state.roll_rad));
  }
  EXPECT_GT(pitch_near_bump, 0.01);
  EXPECT_GT(roll, 0.01);
}

TEST(Simulation, GpsErrorStatisticsMatchTheConfiguration) {
  config::RobotSpec robot = robot_without_lasers();
  robot.gps.correlation_time_s = 10.0;  // many independent samples in a short run
  robot.gps.horizontal_error_rms_m = 2.0;
  robot.gps.multipath_error_rms_m = 1.6;  // the slow part: 1.2 m
  robot.gps.multipath_correlation_s = 2.0;
  Simulation simulation(straight_road(2400.0), robot, SimOptions{});
  StateSink sink;
  simulation.run(sink);
  ASSERT_GT(sink.gps.size(), 7000u);
  double sum_squares = 0.0;
  for (const GpsTruth& epoch : sink.gps) {
    ASSERT_TRUE(epoch.fix) << "open sky";
    sum_squares += epoch.error_m.head<2>().squaredNorm();
  }
  const double mean_square = sum_squares / static_cast<double>(sink.gps.size());
  EXPECT_NEAR(std::sqrt(mean_square), 2.0, 0.2);
  // Each part is a Gauss-Markov process, which keeps exp(-lag / tau) of itself after a lag:
  // the autocorrelation is the two parts' mix.
  const auto autocorrelation = [&](double lag_s) {
    const auto lag = static_cast<std::size_t>(lag_s * robot.gps.rate_hz);
    double product = 0.0;
    for (std::size_t i = lag; i < sink.gps.size(); ++i) {
      product += sink.gps[i].error_m.head<2>().dot(sink.gps[i - lag].error_m.head<2>());
    }
    return product / static_cast<double>(sink.gps.size() - lag) / mean_square;
  };
  const auto expected = [&](double lag_s) {
    const double multipath = 1.6 * 1.6;
    const double slow = 2.0 * 2.0 - multipath;
    return (slow * std::exp(-lag_s / 10.0) + multipath * std::exp(-lag_s / 2.0)) / 4.0;
  };
  EXPECT_NEAR(autocorrelation(2.0), expected(2.0), 0.08);
  EXPECT_NEAR(autocorrelation(10.0), expected(10.0), 0.08);
}

TEST(Simulation, TallBuildingsHideSatellitesAndCanLoseTheFix) {
  World canyon = straight_road(60.0);
  for (const double side : {-1.0, 1.0}) {
    Building wall;
    wall.id = side < 0 ? 1 : 2;
    wall.height_m = 40.0;
    FootprintParameters p;
    p.length_m = 200.0;
    p.width_m = 10.0;
    wall.footprint_m = make_footprint(p, Vec2(30.0, side * 9.0), 0.0);
    canyon.buildings.push_back(wall);
  }
  Simulation simulation(canyon, robot_without_lasers(), SimOptions{});
  StateSink sink;
  simulation.run(sink);
  int without_fix = 0;
  for (const GpsTruth& truth : sink.gps) {
    EXPECT_LT(truth.satellites_visible, 10);
    without_fix += truth.fix ? 0 : 1;
  }
  EXPECT_GT(without_fix, 0);
  EXPECT_EQ(simulation.stats().gps_epochs_without_fix, static_cast<std::uint64_t>(without_fix));
}

// The devices the robot runs, on the simulated ports.
struct PortRig {
  explicit PortRig(const Simulation& simulation)
      : can(clock, {}, pending, sent),
        base(can, odometry, imu,
             [&] {
               devices::SegwayBaseConfig config;
               config.rmp.model = simulation.robot().base.model;
               return config;
             }()),
        horizontal(serial[0], scans, {}),
        vertical(serial[1], scans, {}),
        gps(serial[2], fixes, {}),
        sink(clock, can, ports) {}

  void poll() {
    (void)base.poll(0);
    (void)horizontal.poll(0);
    (void)vertical.poll(0);
    (void)gps.poll(0);
    msg::OdometrySample sample;
    while (odometry.try_pop(sample)) {
      ++odometry_samples;
    }
    msg::ImuSample attitude;
    while (imu.try_pop(attitude)) {
    }
    while (scans.try_pop(scan)) {
      ++scan_count;
    }
    msg::GpsFix fix;
    while (fixes.try_pop(fix)) {
      ++fix_count;
    }
  }

  ManualClock clock;
  std::array<PendingCanFrame, 64> pending{};
  std::array<CanFrame, 4> sent{};
  LoopbackCanBus can;
  SpscQueue<msg::OdometrySample, 16> odometry;
  SpscQueue<msg::ImuSample, 16> imu;
  SpscQueue<msg::LaserScan, 4> scans;
  SpscQueue<msg::GpsFix, 4> fixes;
  std::array<SimSerialPort, 3> serial;
  std::array<SimSerialPort*, 3> ports = {&serial[0], &serial[1], &serial[2]};
  devices::SegwayBase base;
  devices::Lms2xxScanner horizontal;
  devices::Lms2xxScanner vertical;
  devices::GpsReceiver gps;
  SimPorts sink;
  msg::LaserScan scan;
  int odometry_samples = 0;
  int scan_count = 0;
  int fix_count = 0;
};

TEST(Simulation, TheRobotsDevicesReadTheSimulationThroughTheirPorts) {
  Simulation simulation(load_world("usc_block"), config::load_robot("paper_rmp"), options_for(4.0));
  auto rig = std::make_unique<PortRig>(simulation);
  rig->clock.set_ns(simulation.start_ns());
  ASSERT_EQ(rig->horizontal.start(), IoStatus::kOk);
  while (simulation.step(rig->sink)) {
    rig->poll();
  }
  EXPECT_EQ(rig->clock.now_ns(), simulation.now_ns());
  EXPECT_NEAR(rig->odometry_samples, 400, 2);
  const SimStats& stats = simulation.stats();
  EXPECT_EQ(rig->scan_count, static_cast<int>(stats.scans_sent[0] + stats.scans_sent[1]));
  EXPECT_EQ(rig->fix_count, static_cast<int>(stats.gps_epochs));
  EXPECT_EQ(rig->horizontal.mode_switches(), 1u) << "the scanner acknowledged continuous output";
  EXPECT_EQ(rig->serial[0].written().size(), 8u) << "the host's 20 24 request went out";
}

}  // namespace
}  // namespace blockmap::hal::sim
