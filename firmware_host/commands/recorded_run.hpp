// RecordedRun: a folder of recorded device logs (docs/log-formats.md) read through the same
// device layer as on the robot (SegwayBase, GpsReceiver, Lms2xxScanner) over log-backed ports,
// one device's next message at a time. `blockmap replay` merges them itself; the daemon's
// `replay:DIR` source (daemon/sources.hpp) hands them to its pipeline thread.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/devices/gps_receiver.hpp"
#include "blockmap/hal/devices/laser_scanners.hpp"
#include "blockmap/hal/devices/segway_base.hpp"
#include "blockmap/hal/replay/log_ports.hpp"
#include "blockmap/hal/sim/simulated_robot.hpp"

namespace blockmap::cli {

// The recorded devices, each read as far as its next message.
class RecordedRun {
 public:
  // `gps_optional`: a robot without a receiver; a missing gps.nmea reads as no fix.
  RecordedRun(const std::filesystem::path& dir, const hal::devices::SegwayBaseConfig& base_config,
              const std::vector<hal::config::LaserSpec>& lasers, bool gps_optional = false)
      : bus_((dir / "rmp.candump").string()),
        nmea_(gps_optional && !std::filesystem::exists(dir / "gps.nmea")
                  ? std::string("/dev/null")
                  : (dir / "gps.nmea").string()),
        base_(bus_, odometry_, imu_, base_config),
        gps_(nmea_, fixes_, hal::devices::GpsReceiverConfig{}) {
    static_cast<void>(base_.install_filters());
    for (const hal::config::LaserSpec& spec : lasers) {
      auto laser = std::make_unique<Laser>((dir / ("laser_" + spec.name + ".bytelog")).string(),
                                           hal::config::lms2xx_config_for(spec));
      lasers_.push_back(std::move(laser));
    }
  }
  [[nodiscard]] std::string open_error() const {
    if (!bus_.ok()) {
      return bus_.error();
    }
    if (!nmea_.ok()) {
      return nmea_.error();
    }
    for (const auto& laser : lasers_) {
      if (!laser->log.ok()) {
        return laser->log.error();
      }
    }
    return {};
  }
  // The next status group of the base; false at the end of its log.
  bool next_base(msg::OdometrySample& odometry, msg::ImuSample& imu) {
    while (odometry_.size_approx() == 0 && !base_done_) {
      base_done_ = base_.poll(0) == IoStatus::kClosed;
    }
    // The base publishes odometry and IMU together, one pair per group.
    return odometry_.try_pop(odometry) && imu_.try_pop(imu);
  }
  bool next_fix(msg::GpsFix& fix) {
    while (fixes_.size_approx() == 0 && !gps_done_) {
      const IoStatus status = gps_.poll(0);
      gps_done_ = status == IoStatus::kClosed || status == IoStatus::kIoError;
    }
    return fixes_.try_pop(fix);
  }
  // The next scan of laser `i`; false at the end of its log (or where it is damaged).
  bool next_scan(std::size_t i, msg::LaserScan& scan) {
    Laser& laser = *lasers_[i];
    while (laser.scans.size_approx() == 0 && !laser.done) {
      const IoStatus status = laser.device.poll(0);
      laser.done = status == IoStatus::kClosed || status == IoStatus::kIoError;
    }
    return laser.scans.try_pop(scan);
  }
  [[nodiscard]] std::size_t laser_count() const noexcept { return lasers_.size(); }
  [[nodiscard]] const hal::replay::ByteLogFileStream& laser_log(std::size_t i) const {
    return lasers_[i]->log;
  }
  [[nodiscard]] const hal::replay::CandumpFileBus& bus() const { return bus_; }
  [[nodiscard]] const hal::devices::SegwayBase& base() const { return base_; }
  [[nodiscard]] const hal::devices::GpsReceiver& gps() const { return gps_; }
  [[nodiscard]] const hal::devices::Lms2xxScanner& laser(std::size_t i) const {
    return lasers_[i]->device;
  }

 private:
  struct Laser {
    Laser(const std::string& path, const hal::devices::Lms2xxScannerConfig& config)
        : log(path), device(log, scans, config) {}
    hal::replay::ByteLogFileStream log;
    SpscQueue<msg::LaserScan, 4> scans;
    hal::devices::Lms2xxScanner device;
    bool done = false;
  };
  hal::replay::CandumpFileBus bus_;
  hal::replay::FileByteStream nmea_;
  SpscQueue<msg::OdometrySample, 64> odometry_;
  SpscQueue<msg::ImuSample, 64> imu_;
  SpscQueue<msg::GpsFix, 16> fixes_;
  hal::devices::SegwayBase base_;
  hal::devices::GpsReceiver gps_;
  std::vector<std::unique_ptr<Laser>> lasers_;
  bool base_done_ = false;
  bool gps_done_ = false;
};

}  // namespace blockmap::cli
