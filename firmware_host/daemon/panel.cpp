#include "daemon/panel.hpp"

#include <chrono>
#include <ostream>

#include "blockmap/hal/linux/gpiod_line.hpp"
#include "daemon/sources.hpp"

namespace blockmap::cli::daemon {
namespace {

constexpr TimestampNs kFastPeriodNs = kNanosecondsPerSecond / 4;
constexpr TimestampNs kSlowPeriodNs = kNanosecondsPerSecond;
// How long the switch's thread waits for an edge before it looks at the level anyway (an edge
// the kernel merged with the one before still shows in the level) and at stop().
constexpr TimestampNs kSwitchWaitNs = 100'000'000;
constexpr const char* kConsumer = "blockmap";

class GpiodOpener final : public GpioOpener {
 public:
  std::unique_ptr<hal::GpioLine> open(const hal::DeviceAddress& address, GpioUse use,
                                      bool active_low, std::string& error) override {
    auto line = std::make_unique<hal::linux_backend::GpiodLine>();
    error = line->open(address.name, address.line_offset,
                       use == GpioUse::kOutput ? hal::linux_backend::GpioDirection::kOutput
                                               : hal::linux_backend::GpioDirection::kInputWithEdges,
                       active_low, kConsumer);
    if (!error.empty()) {
      return nullptr;
    }
    return line;
  }
};

}  // namespace

const char* to_string(LedPattern pattern) noexcept {
  switch (pattern) {
    case LedPattern::kOff:
      return "off";
    case LedPattern::kSteady:
      return "steady";
    case LedPattern::kFastBlink:
      return "fast blink";
    case LedPattern::kSlowBlink:
      return "slow blink";
  }
  return "?";
}

LedPattern led_pattern(bool mapping_enabled, bool every_device_up) noexcept {
  if (!mapping_enabled) {
    return LedPattern::kSlowBlink;
  }
  return every_device_up ? LedPattern::kSteady : LedPattern::kFastBlink;
}

bool led_level(LedPattern pattern, TimestampNs now_ns) noexcept {
  switch (pattern) {
    case LedPattern::kOff:
      return false;
    case LedPattern::kSteady:
      return true;
    case LedPattern::kFastBlink:
      return now_ns % kFastPeriodNs < kFastPeriodNs / 2;
    case LedPattern::kSlowBlink:
      return now_ns % kSlowPeriodNs < kSlowPeriodNs / 2;
  }
  return false;
}

std::unique_ptr<GpioOpener> gpiod_opener() {
  return std::make_unique<GpiodOpener>();
}

Panel::Panel(std::unique_ptr<GpioOpener> opener) : opener_(std::move(opener)) {}

Panel::~Panel() {
  stop();
}

std::string Panel::start(const hal::config::DaemonConfig& config, std::ostream& err) {
  debounce_ns_ = ns_from_seconds(config.switch_debounce_s);
  if (config.status_led) {
    std::string error;
    led_ = opener_->open(*config.status_led, GpioUse::kOutput, config.status_led_active_low, error);
    if (led_ == nullptr) {
      return "devices.status_led: " + error;
    }
    err << "status LED " << hal::to_string(*config.status_led) << ": up\n";
  }
  if (config.enable_switch) {
    std::string error;
    switch_ = opener_->open(*config.enable_switch, GpioUse::kInputWithEdges,
                            config.enable_switch_active_low, error);
    if (switch_ == nullptr) {
      return "devices.enable_switch: " + error;
    }
    bool enabled = true;
    if (const IoStatus status = switch_->get(enabled); status != IoStatus::kOk) {
      return "devices.enable_switch: " + hal::to_string(*config.enable_switch) +
             ": cannot read the level (" + to_string(status) + ")";
    }
    mapping_enabled_.store(enabled, std::memory_order_release);
    err << "enable switch " << hal::to_string(*config.enable_switch) << ": "
        << (enabled ? "on, mapping" : "off, mapping paused until it is switched on") << '\n';
    thread_ = std::thread([this] { follow_switch(); });
  }
  if (config.gps_pps) {
    std::string error;
    pps_ =
        opener_->open(*config.gps_pps, GpioUse::kInputWithEdges, config.gps_pps_active_low, error);
    if (pps_ == nullptr) {
      return "devices.gps_pps: " + error;
    }
    err << "GPS PPS " << hal::to_string(*config.gps_pps)
        << ": up (fixes are placed on its edges)\n";
    pps_thread_ = std::thread([this] { follow_pps(); });
  }
  return {};
}

void Panel::follow_pps() {
  while (!stop_.load(std::memory_order_acquire)) {
    const hal::GpioEdge edge = pps_->wait_edge(kSwitchWaitNs);
    if (edge.status == IoStatus::kOk && edge.rising) {
      pps_seen_.fetch_add(1, std::memory_order_relaxed);
      static_cast<void>(pps_queue_.try_push(edge.stamp_ns));
    } else if (edge.status != IoStatus::kOk && edge.status != IoStatus::kTimedOut &&
               edge.status != IoStatus::kWouldBlock) {
      std::this_thread::sleep_for(std::chrono::nanoseconds(kSwitchWaitNs));  // not spun
    }
  }
}

void Panel::follow_switch() {
  while (!stop_.load(std::memory_order_acquire)) {
    const hal::GpioEdge edge = switch_->wait_edge(kSwitchWaitNs);
    if (edge.status == IoStatus::kOk) {
      // The contact may still bounce: wait until it has been still for the debounce time.
      while (!stop_.load(std::memory_order_acquire) &&
             switch_->wait_edge(debounce_ns_).status == IoStatus::kOk) {
      }
    } else if (edge.status != IoStatus::kTimedOut && edge.status != IoStatus::kWouldBlock) {
      // A line that fails keeps the last level: a map paused or not is safer than one that
      // flips with a broken wire. The failure is counted and the wait is not spun.
      switch_failures_.fetch_add(1, std::memory_order_relaxed);
      std::this_thread::sleep_for(std::chrono::nanoseconds(kSwitchWaitNs));
      continue;
    }
    bool level = false;
    if (switch_->get(level) != IoStatus::kOk) {
      switch_failures_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    if (level != mapping_enabled_.load(std::memory_order_relaxed)) {
      mapping_enabled_.store(level, std::memory_order_release);
      switch_changes_.fetch_add(1, std::memory_order_relaxed);
    }
  }
}

void Panel::show(LedPattern pattern, TimestampNs now_ns) {
  if (led_ == nullptr) {
    return;
  }
  const bool level = led_level(pattern, now_ns);
  if (led_known_ && level == led_shown_) {
    return;
  }
  // A failed write is counted by the line and tried again at the next call.
  led_known_ = led_->set(level) == IoStatus::kOk;
  led_shown_ = level;
}

void Panel::report_changes(std::ostream& err) {
  const std::uint64_t changes = switch_changes();
  if (changes == changes_reported_) {
    return;
  }
  changes_reported_ = changes;
  err << "enable switch: "
      << (mapping_enabled_.load(std::memory_order_acquire) ? "on, mapping" : "off, mapping paused")
      << '\n';
}

void Panel::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) {
    thread_.join();
  }
  if (pps_thread_.joinable()) {
    pps_thread_.join();
  }
  if (led_ != nullptr) {
    led_known_ = false;
    show(LedPattern::kOff, 0);
  }
}

std::uint64_t Panel::led_failures() const noexcept {
  return led_ != nullptr ? led_->failures() : 0;
}

}  // namespace blockmap::cli::daemon
