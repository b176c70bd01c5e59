// `blockmap decode nmea`: the object of docs/formats.md, decoded NMEA, for every sentence that
// carries a position or a time; rejected sentences as {"error": reason, "line": N}.
#include <cstdio>
#include <ostream>
#include <span>
#include <string>

#include "blockmap/hal/protocol/nmea.hpp"
#include "cli.hpp"
#include "commands/decoders.hpp"

namespace blockmap::cli {
namespace {

std::string time_of_day(std::int32_t milliseconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%02d:%02d:%02d.%03d", milliseconds / 3'600'000,
                milliseconds / 60'000 % 60, milliseconds / 1000 % 60, milliseconds % 1000);
  return text;
}

std::string date_of(const msg::GpsFix& fix) {
  char text[32];
  std::snprintf(text, sizeof text, "%04u-%02u-%02u", static_cast<unsigned>(fix.utc_year),
                static_cast<unsigned>(fix.utc_month), static_cast<unsigned>(fix.utc_day));
  return text;
}

const char* mode_name(msg::GpsFixMode mode) {
  switch (mode) {
    case msg::GpsFixMode::kNone:
      return "none";
    case msg::GpsFixMode::k2d:
      return "2d";
    case msg::GpsFixMode::k3d:
      return "3d";
    case msg::GpsFixMode::kUnknown:
      break;
  }
  return nullptr;
}

// The object of docs/formats.md, decoded NMEA, of a sentence that carries a position or a time.
Json nmea_json(const hal::protocol::nmea::Sentence& sentence) {
  const msg::GpsFix& fix = sentence.fix;
  Json line;
  line["sentence"] = to_string(sentence.type);
  line["talker"] = sentence.talker.data();
  line["time"] = fix.has_time ? Json(time_of_day(fix.utc_milliseconds_of_day)) : Json();
  line["date"] = fix.has_date ? Json(date_of(fix)) : Json();
  line["lat"] = fix.has_position ? rounded(fix.latitude_deg, 9) : Json();
  line["lon"] = fix.has_position ? rounded(fix.longitude_deg, 9) : Json();
  line["alt_m"] = fix.has_altitude ? rounded(fix.altitude_msl_m, 4) : Json();
  line["quality"] = fix.has_quality ? Json(static_cast<int>(fix.quality)) : Json();
  const char* mode = mode_name(fix.mode);
  line["mode"] = mode != nullptr ? Json(mode) : Json();
  line["sats"] = fix.has_satellites ? Json(fix.satellites_used) : Json();
  line["hdop"] = fix.has_hdop ? rounded(fix.hdop, 3) : Json();
  line["speed_mps"] = fix.has_velocity ? rounded(fix.speed_mps, 6) : Json();
  line["course_deg"] = fix.has_course ? rounded(fix.course_deg, 6) : Json();
  return line;
}

bool carries_position_or_time(hal::protocol::nmea::SentenceType type) {
  using hal::protocol::nmea::SentenceType;
  return type == SentenceType::kGga || type == SentenceType::kRmc || type == SentenceType::kGll ||
         type == SentenceType::kGns || type == SentenceType::kZda;
}

}  // namespace

int decode_nmea(CaptureReader& capture, std::ostream& out, std::ostream& err) {
  namespace nmea = hal::protocol::nmea;
  LineCounter lines;
  nmea::Decoder decoder;
  // The keys are a contract (docs/formats.md, decoded NMEA): a timed capture's receive times
  // are not added; the sentences carry their own UTC.
  std::span<const std::uint8_t> piece;
  TimestampNs stamp_ns = 0;
  while (capture.next(piece, stamp_ns)) {
    lines.feed(piece);
    std::span<const std::uint8_t> rest = piece;
    while (!rest.empty()) {
      const nmea::Decoder::Step step = decoder.push(rest, stamp_ns);
      rest = rest.subspan(step.consumed);
      if (step.sentence != nullptr && carries_position_or_time(step.sentence->type)) {
        out << nmea_json(*step.sentence).dump() << '\n';
      } else if (step.rejected) {
        Json line;
        line["error"] = nmea::to_string(step.reason);
        line["line"] = lines.line_of(step.start_offset);
        out << line.dump() << '\n';
      }
    }
  }
  err << "nmea: " << decoder.sentences_decoded() << " sentences decoded";
  print_drops(err, decoder.drops());
  err << '\n';
  return kExitOk;
}

}  // namespace blockmap::cli
