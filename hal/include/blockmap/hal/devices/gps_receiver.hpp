// GpsReceiver: an NMEA GNSS receiver on a ByteStream. Each poll() reads once, decodes, and
// publishes one msg::GpsFix per epoch into the runtime's queue.
//
// Which sentence makes the fix: GGA (or GNS) when the receiver sends it, since it carries the
// fix quality, satellites, HDOP and altitude that the localizer weighs; RMC or GLL only when no
// GGA/GNS has come for `primary_timeout_ns` (receivers configured for RMC only). Speed, course
// and date of an RMC or VTG with the same UTC time as the GGA are merged in when they come first.
#pragma once

#include <array>
#include <cstdint>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/byte_stream.hpp"
#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/msg/gps_fix.hpp"

namespace blockmap::hal::devices {

struct GpsReceiverConfig {
  protocol::nmea::Config nmea;
  TimestampNs primary_timeout_ns = 3 * kNanosecondsPerSecond;
};

class GpsReceiver {
 public:
  GpsReceiver(ByteStream& port, SpscQueueRef<msg::GpsFix>& fixes, const GpsReceiverConfig& config);

  // Reads what the port has (waiting at most timeout_ns), decodes it and publishes fixes. Returns
  // the port's status: kClosed or kDeviceLost tell the watchdog the receiver is gone.
  IoStatus poll(TimestampNs timeout_ns);

  [[nodiscard]] const protocol::nmea::Decoder& decoder() const noexcept { return decoder_; }
  [[nodiscard]] std::uint64_t fixes_published() const noexcept { return published_.value(); }
  // Fixes the queue had no room for (the pipeline fell behind).
  [[nodiscard]] std::uint64_t fixes_rejected() const noexcept { return rejected_.value(); }

 private:
  void handle(const protocol::nmea::Sentence& sentence);
  void publish(const msg::GpsFix& fix);

  ByteStream& port_;
  SpscQueueRef<msg::GpsFix>& fixes_;
  GpsReceiverConfig config_;
  protocol::nmea::Decoder decoder_;
  std::array<std::uint8_t, 512> read_buffer_{};
  msg::GpsFix velocity_;  // the latest RMC/VTG speed, course and date, merged into fixes
  bool has_velocity_ = false;
  TimestampNs last_primary_ns_ = 0;
  bool seen_primary_ = false;
  MonotonicCounter published_;
  MonotonicCounter rejected_;
};

}  // namespace blockmap::hal::devices
