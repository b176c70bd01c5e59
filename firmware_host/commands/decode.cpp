// `blockmap decode PROTOCOL FILE`: decoded messages of a raw capture, one JSON object a line
// (docs/formats.md, command line; decoded NMEA fixes the NMEA keys). Decoding errors are
// reported in line and decoding goes on; a summary of what was dropped, and why, goes to stderr.
// The capture is read piece by piece (CaptureReader): memory does not grow with its length.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <ostream>
#include <span>
#include <string>
#include <vector>

#include "cli.hpp"
#include "commands/commands.hpp"
#include "commands/decoders.hpp"

namespace blockmap::cli {
namespace {

struct DecoderEntry {
  const char* name;
  const char* description;
  DecoderFunction decode;
};

constexpr DecoderEntry kDecoders[] = {
    {"nmea", "NMEA 0183 byte stream from a GNSS receiver", &decode_nmea},
    {"rmp", "Segway RMP CAN log (candump format, or id:XXXX byte lines)", &decode_rmp},
    {"scip2", "Hokuyo SCIP 2.0 byte stream (URG/UTM scanners)", &decode_scip2},
    {"lms2xx", "SICK LMS 200/291 serial byte stream (telegrams, ACK/NAK)", &decode_lms2xx},
    {"cola", "SICK TiM/LMS1xx/LMS5xx CoLa A or B stream (raw, or pcapng.json)", &decode_cola},
};

}  // namespace

void LineCounter::feed(std::span<const std::uint8_t> bytes) {
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    if (bytes[i] == '\n') {
      newlines_.push_back(fed_ + i);
    }
  }
  fed_ += bytes.size();
  while (!newlines_.empty() && newlines_.front() + kLookBackBytes < fed_) {
    newlines_.pop_front();
    ++older_;
  }
}

std::size_t LineCounter::line_of(std::uint64_t offset) const {
  return 1 + older_ +
         static_cast<std::size_t>(std::lower_bound(newlines_.begin(), newlines_.end(), offset) -
                                  newlines_.begin());
}

void add_time(Json& line, const CaptureReader& capture, TimestampNs stamp_ns) {
  if (capture.timed()) {
    line["t_s"] = rounded(seconds_from_ns(stamp_ns), 6);
  }
}

Json rounded(double value, int decimals) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return std::strtod(text, nullptr);
}

Json ranges_json(const msg::LaserScan& scan, int decimals) {
  Json ranges = Json::array();
  for (std::size_t i = 0; i < scan.beam_count; ++i) {
    ranges.push_back(scan.status[i] == msg::BeamStatus::kValid
                         ? rounded(static_cast<double>(scan.ranges_m[i]), decimals)
                         : Json());
  }
  return ranges;
}

Command add_decode_command(CLI::App& app) {
  CLI::App* decode = app.add_subcommand(
      "decode", "Decode a raw device capture into JSON Lines (one message a line)");
  auto protocol = std::make_shared<std::string>();
  auto path = std::make_shared<std::string>();
  std::vector<std::string> names;
  std::string help = "the device protocol:";
  for (const DecoderEntry& entry : kDecoders) {
    names.emplace_back(entry.name);
    help += std::string("\n  ") + entry.name + ": " + entry.description;
  }
  decode->add_option("protocol", *protocol, help)->required()->check(CLI::IsMember(names));
  decode->add_option("file", *path, "the capture; - reads standard input")->required();
  return {decode, [protocol, path](std::ostream& out, std::ostream& err) {
            CaptureReader capture(*path);
            if (const std::string problem = capture.open(); !problem.empty()) {
              err << "blockmap: " << problem << '\n';
              return kExitFailure;
            }
            for (const DecoderEntry& entry : kDecoders) {
              if (*protocol == entry.name) {
                const int status = entry.decode(capture, out, err);
                if (!capture.damage().empty()) {
                  err << "blockmap: " << capture.damage() << '\n';
                  return kExitFailure;
                }
                return status;
              }
            }
            return kExitUsage;  // unreachable: CLI11 checked the name
          }};
}

}  // namespace blockmap::cli
