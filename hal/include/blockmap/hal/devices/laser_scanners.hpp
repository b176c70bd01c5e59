// Laser scanners on their ports: each start() sends the commands that make the device stream
// scans, each poll() reads once, decodes and publishes every complete scan into the runtime's
// queue. Scans are stamped by the codec with the arrival of their first byte, minus the
// configured latency (transfer and sweep time, docs/protocols.md section 6).
#pragma once

#include <array>
#include <cstdint>

#include "blockmap/core/counter.hpp"
#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/byte_stream.hpp"
#include "blockmap/hal/protocol/hokuyo_scip2.hpp"
#include "blockmap/hal/protocol/sick_cola.hpp"
#include "blockmap/hal/protocol/sick_lms2xx.hpp"
#include "blockmap/hal/usb_bulk.hpp"
#include "blockmap/msg/laser_scan.hpp"

namespace blockmap::hal::devices {

// What every scanner device counts and how it publishes.
class ScanPublisher {
 public:
  // beam_interval_s: the time between two beams, stamped on scans whose telegrams do not say
  // (0: leave it unknown).
  ScanPublisher(SpscQueueRef<msg::LaserScan>& scans, TimestampNs latency_ns,
                double beam_interval_s = 0.0)
      : scans_(scans), latency_ns_(latency_ns), beam_interval_s_(beam_interval_s) {}

  [[nodiscard]] std::uint64_t scans_published() const noexcept { return published_.value(); }
  // Scans the queue had no room for (the pipeline fell behind).
  [[nodiscard]] std::uint64_t scans_rejected() const noexcept { return rejected_.value(); }

 protected:
  void publish(const msg::LaserScan& scan);

 private:
  SpscQueueRef<msg::LaserScan>& scans_;
  TimestampNs latency_ns_;
  double beam_interval_s_;
  msg::LaserScan stamped_;
  MonotonicCounter published_;
  MonotonicCounter rejected_;
};

struct Lms2xxScannerConfig {
  protocol::sick_lms2xx::Config codec;
  // Back-dating of each scan: the telegram's transfer starts after the sweep it reports.
  TimestampNs latency_ns = 0;
  // The time between two beams (the B0 telegram does not carry it); 0: unknown.
  double beam_interval_s = 0.0;
  // The baud-rate handshake (docs/protocols.md 2.4): an LMS2xx powers up at 9600 Bd. With
  // power_up_baud set and line_baud another rate, start() first asks for continuous output at
  // line_baud (a scanner that kept that rate since the last start answers); when nothing
  // answers within reply_timeout_ns, it asks at power_up_baud for line_baud (20 4x, answered
  // at the old rate), moves the port to line_baud, and asks for continuous output again.
  // 0: no handshake (the scanner is already at the line's rate, or it answers nothing, as the
  // simulated and recorded ones do).
  std::uint32_t line_baud = 0;
  std::uint32_t power_up_baud = 0;
  TimestampNs reply_timeout_ns = 200'000'000;  // the ACK is due within 60 ms, the reply after
};

// An LMS2xx's timing when one mirror turn makes a scan (the 1 deg variants; docs/protocols.md 2):
// the mirror turns at 75 Hz, so beams are resolution / 360 of a turn apart, and the field is
// centred on the half turn facing forward (a 100 deg field starts 40 deg into it). The
// telegram's first byte leaves about processing_s after that half turn; the stamp moves back
// to the first beam.
[[nodiscard]] Lms2xxScannerConfig lms2xx_single_turn_timing(double field_deg, double resolution_deg,
                                                            double processing_s = 0.001);

// SICK LMS 200/291 on a serial line (docs/protocols.md 2.5: continuous output after 20 24).
class Lms2xxScanner : public ScanPublisher {
 public:
  Lms2xxScanner(ByteStream& port, SpscQueueRef<msg::LaserScan>& scans,
                const Lms2xxScannerConfig& config);

  // Requests continuous output of all values. The scanner acknowledges with 06 and an A0 reply,
  // which poll() reads (see acks() and mode_switches()). With the baud-rate handshake
  // configured, first brings the scanner and the port to the line's rate; kTimedOut when the
  // scanner answers at neither rate.
  IoStatus start();
  IoStatus poll(TimestampNs timeout_ns);

  [[nodiscard]] const protocol::sick_lms2xx::Decoder& decoder() const noexcept { return decoder_; }
  // A0 replies with a success status (00), i.e. accepted mode changes.
  [[nodiscard]] std::uint64_t mode_switches() const noexcept { return mode_switches_.value(); }

 private:
  void handle(const protocol::sick_lms2xx::Decoder::Step& step);
  // Sends a request and reads until the scanner accepts a mode switch (A0 00) or sends a
  // scan; whether it did within the reply time-out.
  bool request_answered(std::span<const std::uint8_t> bytes);
  [[nodiscard]] IoStatus request(std::span<const std::uint8_t> bytes);

  ByteStream& port_;
  Lms2xxScannerConfig config_;
  protocol::sick_lms2xx::Decoder decoder_;
  std::array<std::uint8_t, 1024> read_buffer_{};
  MonotonicCounter mode_switches_;
};

struct UrgScannerConfig {
  protocol::hokuyo_scip2::Config codec;
  std::uint32_t cluster = 1;  // steps per value
  TimestampNs latency_ns = 0;
};

// Hokuyo URG/UTM on USB CDC-ACM or serial (docs/protocols.md 4.1-4.5): switch to SCIP 2.0, read the
// geometry (PP), laser on (BM), then continuous three-character scans over the valid steps (MD).
class UrgScanner : public ScanPublisher {
 public:
  UrgScanner(ByteStream& port, SpscQueueRef<msg::LaserScan>& scans, const UrgScannerConfig& config);

  IoStatus start();
  IoStatus poll(TimestampNs timeout_ns);

  [[nodiscard]] const protocol::hokuyo_scip2::Decoder& decoder() const noexcept { return decoder_; }
  // Replies whose status is neither 00 nor 99 (a command the firmware refused).
  [[nodiscard]] std::uint64_t error_replies() const noexcept { return error_replies_.value(); }

 private:
  ByteStream& port_;
  UrgScannerConfig config_;
  protocol::hokuyo_scip2::Decoder decoder_;
  std::array<std::uint8_t, 1024> read_buffer_{};
  MonotonicCounter error_replies_;
};

struct TimScannerConfig {
  protocol::sick_cola::Config codec;  // framing kDetect reads either dialect
  // Over USB a TiM speaks CoLa A (docs/protocols.md 3.1); the start command goes out in this
  // dialect.
  protocol::sick_cola::Dialect dialect = protocol::sick_cola::Dialect::kColaA;
  TimestampNs transfer_timeout_ns = kNanosecondsPerSecond;  // sick_tim uses 1000 ms
  TimestampNs latency_ns = 0;
};

// SICK TiM on USB bulk endpoints (docs/protocols.md 3.1, 3.3): start() enables the scan events
// (sEN LMDscandata 1); poll() runs one IN transfer through the CoLa decoder.
class TimScanner : public ScanPublisher {
 public:
  TimScanner(UsbBulk& usb, SpscQueueRef<msg::LaserScan>& scans, const TimScannerConfig& config);

  IoStatus start();
  // kDeviceLost after a hot-unplug: the bytes of a telegram cut off by it are dropped (flush) so
  // that the stream restarts cleanly after reconnecting.
  IoStatus poll(TimestampNs timeout_ns);

  [[nodiscard]] const protocol::sick_cola::Decoder& decoder() const noexcept { return decoder_; }

 private:
  UsbBulk& usb_;
  TimScannerConfig config_;
  protocol::sick_cola::StaticDecoder<> decoder_;
  std::array<std::uint8_t, 4096> transfer_buffer_{};
};

}  // namespace blockmap::hal::devices
