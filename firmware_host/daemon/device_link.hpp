// DeviceLink: one device's reader thread on the robot. It opens the device's port,
// starts the device, and polls it, each poll reading, decoding and publishing into the
// device's SPSC queue. It is also the device's watchdog:
// - a port that reports the device gone (kDeviceLost, kClosed, kIoError) is closed and opened
//   again after a wait that doubles from reconnect_first_s up to reconnect_max_s;
// - a device that publishes nothing for silent_after_s is reopened the same way (a laser that
//   was power-cycled needs its start command again; a receiver that stopped may come back).
// What happened is counted in LinkHealth, which any thread may read; nothing here allocates
// after start() (the ports' error strings aside, on the way to a reconnect).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "blockmap/core/status.hpp"
#include "blockmap/core/time.hpp"
#include "blockmap/hal/clock.hpp"

namespace blockmap::cli::daemon {

enum class LinkState : std::uint8_t {
  kConnecting = 0,  // opening the port, or waiting to open it again
  kUp,              // open, publishing
  kSilent,          // open, but nothing published for silent_after_s (then reopened)
  kLost,            // the port reported the device gone; waiting to reopen
  kStopped,         // the thread has ended
};
[[nodiscard]] const char* to_string(LinkState state) noexcept;

struct LinkTiming {
  TimestampNs poll_timeout_ns = 20'000'000;  // a poll's longest wait: how soon stop() is seen
  TimestampNs silent_after_ns = 2 * kNanosecondsPerSecond;
  TimestampNs reconnect_first_ns = kNanosecondsPerSecond / 4;
  TimestampNs reconnect_max_ns = 8 * kNanosecondsPerSecond;
};

// What a link reports; written by its thread only, read by anyone.
struct LinkHealth {
  std::atomic<LinkState> state{LinkState::kConnecting};
  std::atomic<std::uint64_t> opens{0};  // successful opens (the first one included)
  std::atomic<std::uint64_t> open_failures{0};
  std::atomic<std::uint64_t> losses{0};    // the port reported the device gone
  std::atomic<std::uint64_t> silences{0};  // the watchdog found it silent
  std::atomic<TimestampNs> last_message_ns{0};
  // Everything this link will publish from now on is stamped at or after this minus the
  // device's latency: the pipeline's merge releases messages up to the links' least watermark.
  std::atomic<TimestampNs> watermark_ns{0};
};

// The device behind a link: how to (re)open it, poll it and count what it published.
struct LinkDevice {
  // Opens the port and starts the device; empty when it worked, else one line why not.
  std::function<std::string()> open;
  std::function<void()> close;
  std::function<IoStatus(TimestampNs timeout_ns)> poll;
  std::function<std::uint64_t()> published;  // messages published so far (monotonic)
};

class DeviceLink {
 public:
  DeviceLink(std::string name, LinkDevice device, const LinkTiming& timing,
             const hal::Clock& clock);
  DeviceLink(const DeviceLink&) = delete;
  DeviceLink& operator=(const DeviceLink&) = delete;
  ~DeviceLink();

  // Opens the device once on the calling thread (so that start-up can report its state), then
  // runs the reader thread, which keeps it open.
  void start();
  // Asks the thread to end (seen within one poll timeout) and joins it.
  void stop();

  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] const LinkHealth& health() const noexcept { return health_; }
  // The reason of the last failed open or loss (for start-up and the log); set before the
  // state changes, read after it.
  [[nodiscard]] std::string last_problem() const;

 private:
  void run();
  // Opens the port; on failure, waits the backoff (or until stop) and says false.
  bool try_open();
  void wait_backoff();
  void set_problem(const std::string& problem);

  std::string name_;
  LinkDevice device_;
  LinkTiming timing_;
  const hal::Clock& clock_;
  LinkHealth health_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  bool open_ = false;
  TimestampNs backoff_ns_ = 0;
  std::uint64_t published_seen_ = 0;
  mutable std::mutex problem_lock_;
  std::string problem_;
};

}  // namespace blockmap::cli::daemon
