#include "daemon/device_link.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

namespace blockmap::cli::daemon {
namespace {

// How long a stop request may wait while the link sleeps before reopening.
constexpr TimestampNs kStopCheckNs = 10'000'000;

bool device_gone(IoStatus status) noexcept {
  return status == IoStatus::kDeviceLost || status == IoStatus::kClosed ||
         status == IoStatus::kIoError;
}

}  // namespace

const char* to_string(LinkState state) noexcept {
  switch (state) {
    case LinkState::kConnecting:
      return "connecting";
    case LinkState::kUp:
      return "up";
    case LinkState::kSilent:
      return "silent";
    case LinkState::kLost:
      return "lost";
    case LinkState::kStopped:
      return "stopped";
  }
  return "?";
}

DeviceLink::DeviceLink(std::string name, LinkDevice device, const LinkTiming& timing,
                       const hal::Clock& clock)
    : name_(std::move(name)), device_(std::move(device)), timing_(timing), clock_(clock) {
  backoff_ns_ = timing_.reconnect_first_ns;
}

DeviceLink::~DeviceLink() {
  stop();
}

void DeviceLink::start() {
  const TimestampNs now_ns = clock_.now_ns();
  health_.watermark_ns.store(now_ns, std::memory_order_release);
  health_.last_message_ns.store(now_ns, std::memory_order_relaxed);
  if (const std::string problem = device_.open(); problem.empty()) {
    open_ = true;
    health_.opens.fetch_add(1, std::memory_order_relaxed);
    health_.state.store(LinkState::kUp, std::memory_order_release);
  } else {
    set_problem(problem);
    health_.open_failures.fetch_add(1, std::memory_order_relaxed);
    health_.state.store(LinkState::kConnecting, std::memory_order_release);
  }
  published_seen_ = device_.published();
  thread_ = std::thread([this] { run(); });
}

void DeviceLink::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) {
    thread_.join();
  }
  if (open_) {
    device_.close();
    open_ = false;
  }
  health_.state.store(LinkState::kStopped, std::memory_order_release);
}

std::string DeviceLink::last_problem() const {
  const std::lock_guard<std::mutex> lock(problem_lock_);
  return problem_;
}

void DeviceLink::set_problem(const std::string& problem) {
  const std::lock_guard<std::mutex> lock(problem_lock_);
  problem_ = problem;
}

void DeviceLink::wait_backoff() {
  const TimestampNs until_ns = clock_.now_ns() + backoff_ns_;
  while (!stop_.load(std::memory_order_acquire)) {
    const TimestampNs now_ns = clock_.now_ns();
    // Nothing will come from this link before it is open again: it holds no one back.
    health_.watermark_ns.store(now_ns, std::memory_order_release);
    if (now_ns >= until_ns) {
      break;
    }
    std::this_thread::sleep_for(
        std::chrono::nanoseconds(std::min(kStopCheckNs, until_ns - now_ns)));
  }
  backoff_ns_ = std::min(backoff_ns_ * 2, timing_.reconnect_max_ns);
}

bool DeviceLink::try_open() {
  if (const std::string problem = device_.open(); !problem.empty()) {
    set_problem(problem);
    health_.open_failures.fetch_add(1, std::memory_order_relaxed);
    wait_backoff();
    return false;
  }
  open_ = true;
  health_.opens.fetch_add(1, std::memory_order_relaxed);
  // Silence is counted from the reopening, not from the last message before the loss.
  health_.last_message_ns.store(clock_.now_ns(), std::memory_order_relaxed);
  published_seen_ = device_.published();
  health_.state.store(LinkState::kUp, std::memory_order_release);
  return true;
}

void DeviceLink::run() {
  while (!stop_.load(std::memory_order_acquire)) {
    if (!open_) {
      if (!try_open()) {
        continue;
      }
    }
    const IoStatus status = device_.poll(timing_.poll_timeout_ns);
    const TimestampNs now_ns = clock_.now_ns();
    health_.watermark_ns.store(now_ns, std::memory_order_release);
    if (const std::uint64_t published = device_.published(); published != published_seen_) {
      published_seen_ = published;
      health_.last_message_ns.store(now_ns, std::memory_order_relaxed);
      if (health_.state.load(std::memory_order_relaxed) != LinkState::kUp) {
        health_.state.store(LinkState::kUp, std::memory_order_release);
      }
      backoff_ns_ = timing_.reconnect_first_ns;
    }
    const bool gone = device_gone(status);
    const bool silent =
        now_ns - health_.last_message_ns.load(std::memory_order_relaxed) > timing_.silent_after_ns;
    if (!gone && !silent) {
      continue;
    }
    set_problem(gone
                    ? std::string("the port reported ") + blockmap::to_string(status)
                    : "nothing for " + std::to_string(timing_.silent_after_ns / 1'000'000) + " ms");
    (gone ? health_.losses : health_.silences).fetch_add(1, std::memory_order_relaxed);
    health_.state.store(gone ? LinkState::kLost : LinkState::kSilent, std::memory_order_release);
    device_.close();
    open_ = false;
    wait_backoff();
  }
}

}  // namespace blockmap::cli::daemon
