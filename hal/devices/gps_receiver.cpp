#include "blockmap/hal/devices/gps_receiver.hpp"

namespace blockmap::hal::devices {

namespace nmea = protocol::nmea;

GpsReceiver::GpsReceiver(ByteStream& port, SpscQueueRef<msg::GpsFix>& fixes,
                         const GpsReceiverConfig& config)
    : port_(port), fixes_(fixes), config_(config), decoder_(config.nmea) {}

IoStatus GpsReceiver::poll(TimestampNs timeout_ns) {
  const ReadResult read = port_.read(read_buffer_, timeout_ns);
  std::span<const std::uint8_t> rest(read_buffer_.data(), read.bytes);
  while (!rest.empty()) {
    const nmea::Decoder::Step step = decoder_.push(rest, read.stamp_ns);
    rest = rest.subspan(step.consumed);
    if (step.sentence != nullptr) {
      handle(*step.sentence);
    }
  }
  return read.status;
}

void GpsReceiver::handle(const nmea::Sentence& sentence) {
  const msg::GpsFix& fix = sentence.fix;
  const TimestampNs now_ns = fix.header.stamp_ns;
  switch (sentence.type) {
    case nmea::SentenceType::kGga:
    case nmea::SentenceType::kGns: {
      seen_primary_ = true;
      last_primary_ns_ = now_ns;
      msg::GpsFix merged = fix;
      if (has_velocity_ && velocity_.has_time && fix.has_time &&
          velocity_.utc_milliseconds_of_day == fix.utc_milliseconds_of_day) {
        merged.has_velocity = velocity_.has_velocity;
        merged.speed_mps = velocity_.speed_mps;
        merged.has_course = velocity_.has_course;
        merged.course_deg = velocity_.course_deg;
        merged.has_date = velocity_.has_date;
        merged.utc_year = velocity_.utc_year;
        merged.utc_month = velocity_.utc_month;
        merged.utc_day = velocity_.utc_day;
      }
      publish(merged);
      break;
    }
    case nmea::SentenceType::kRmc:
    case nmea::SentenceType::kGll:
      if (sentence.type == nmea::SentenceType::kRmc) {
        velocity_ = fix;
        has_velocity_ = true;
      }
      if (!seen_primary_ || now_ns - last_primary_ns_ > config_.primary_timeout_ns) {
        publish(fix);
      }
      break;
    case nmea::SentenceType::kVtg:
      // VTG has no time of its own: it belongs to the epoch of the last RMC, if any.
      velocity_.has_velocity = fix.has_velocity;
      velocity_.speed_mps = fix.speed_mps;
      velocity_.has_course = fix.has_course;
      velocity_.course_deg = fix.course_deg;
      break;
    default:
      break;  // GSA feeds the decoder's fix mode; GSV and ZDA carry no position
  }
}

void GpsReceiver::publish(const msg::GpsFix& fix) {
  if (fixes_.try_push(fix)) {
    published_.increment();
  } else {
    rejected_.increment();
  }
}

}  // namespace blockmap::hal::devices
