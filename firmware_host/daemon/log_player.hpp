// LogPlayer: a folder of recorded device logs (docs/log-formats.md) played onto real
// interfaces at the pace they were recorded, as the robot's devices would put them there:
// each serial log (laser_<name>.bytelog, gps.nmea) onto a pseudo-terminal whose other end is
// linked at PTY_DIR/<name> for the daemon to open as a serial port, and the CAN log onto a
// CanSink (a SocketCAN interface, or a test's bus). `blockmap play` is this, for trying the
// daemon against recorded bytes on the robot's computer or in the test rig (docs/design.md);
// can-utils' canplayer can play the CAN log instead.
//
// The logs share one clock: the CAN log's and the byte logs' receive stamps, and the NMEA
// sentences' own UTC (their day from the CAN log, else the lasers', else their own RMC). A
// serial line that was unplugged discards what it would have carried, as a pulled cable
// does, and one nobody reads loses what does not fit, after one wait for a slow reader, as a
// real line does; the fault hooks (unplug, replug, inject, mute) are thread-safe, for
// fault tests.
#pragma once

#include <atomic>
#include <filesystem>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "blockmap/hal/can_frame.hpp"

namespace blockmap::cli::daemon {

class CanSink {
 public:
  CanSink() = default;
  CanSink(const CanSink&) = delete;
  CanSink& operator=(const CanSink&) = delete;
  virtual ~CanSink() = default;
  // Sends one recorded frame; false when it could not (counted by the player).
  virtual bool send(const hal::CanFrame& frame) = 0;
};

struct PlayerCounters {
  std::uint64_t can_frames = 0;
  std::uint64_t can_refused = 0;
  std::uint64_t serial_bytes = 0;
  std::uint64_t serial_discarded = 0;  // for a line unplugged or muted
};

class LogPlayer {
 public:
  LogPlayer();
  ~LogPlayer();
  LogPlayer(const LogPlayer&) = delete;
  LogPlayer& operator=(const LogPlayer&) = delete;

  // Opens the logs in `dir` (the lasers robot.toml names, gps.nmea, rmp.candump when `can` is
  // given) and a pseudo-terminal for each serial log, linked at pty_dir/<name>. Empty when it
  // worked, else one line why not.
  [[nodiscard]] std::string open(const std::filesystem::path& dir,
                                 const std::filesystem::path& pty_dir, CanSink* can,
                                 double speed = 1.0);
  // The serial lines' names (laser_horizontal, ..., gps) and where their ends are linked.
  [[nodiscard]] std::vector<std::string> serial_names() const;
  [[nodiscard]] std::filesystem::path link_of(const std::string& name) const;

  // Plays from now to the end of the logs, or until `stop`; the log time played, s.
  double play(const std::atomic<bool>& stop);

  // Fault hooks, from any thread.
  // The line's far end goes away: the daemon's port reads a hang-up; bytes are discarded.
  void unplug(const std::string& name);
  // A new pseudo-terminal at the same link (a cable plugged back in).
  void replug(const std::string& name);
  // Puts `bytes` on the line now, between the recorded ones (noise, a corrupted stream).
  void inject(const std::string& name, std::span<const std::uint8_t> bytes);
  // Stops (or resumes) carrying the line's bytes, the port staying open (a receiver that
  // stops talking).
  void mute(const std::string& name, bool muted);

  [[nodiscard]] PlayerCounters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace blockmap::cli::daemon
