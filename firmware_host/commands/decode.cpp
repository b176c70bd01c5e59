// `blockmap decode PROTOCOL FILE`: decoded messages of a raw capture, one JSON object a line
// (docs/formats.md, command line; decoded NMEA fixes the NMEA keys). Decoding errors are
// reported in line and decoding goes on; a summary of what was dropped, and why, goes to stderr.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <ostream>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "blockmap/hal/files.hpp"
#include "blockmap/hal/protocol/byte_log.hpp"
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

// A timestamped byte log -> the device's bytes and their chunks. A damaged record ends the
// log: what came before it is kept and decoded, and the damage is reported.
bool unpack_byte_log(Capture& capture, std::ostream& err) {
  namespace byte_log = hal::protocol::byte_log;
  std::vector<std::uint8_t> file;
  file.swap(capture.bytes);
  const std::span<const std::uint8_t> records =
      std::span<const std::uint8_t>(file).subspan(byte_log::kMagic.size());
  byte_log::Reader reader(records);
  byte_log::Record record;
  capture.timed = true;
  for (;;) {
    const std::size_t offset = byte_log::kMagic.size() + reader.offset();
    const byte_log::ParseError error = reader.next(record);
    if (error == byte_log::ParseError::kEnd) {
      return true;
    }
    if (error != byte_log::ParseError::kNone) {
      err << "blockmap: " << capture.path << ": byte log record at offset " << offset << ": "
          << byte_log::to_string(error) << "; decoding the records before it\n";
      return false;
    }
    if (record.header.direction == byte_log::Direction::kToDevice) {
      ++capture.host_records;
      continue;
    }
    capture.chunks.push_back({capture.bytes.size(), record.bytes.size(), record.header.stamp_ns});
    capture.bytes.insert(capture.bytes.end(), record.bytes.begin(), record.bytes.end());
  }
}

// Captures are decoded whole: an hour of a laser's bytes is about 200 MiB.
constexpr std::size_t kMaxCaptureBytes = std::size_t{1} << 30;

// Reads a whole capture ("-" is standard input). Offline decoding may allocate: it is not the
// onboard runtime. False with a message when the file cannot be read; a damaged byte log is
// reported and its good records kept (`intact` false).
bool read_capture(Capture& capture, bool& intact, std::ostream& err) {
  if (capture.path == "-") {
    capture.bytes.assign(std::istreambuf_iterator<char>(std::cin),
                         std::istreambuf_iterator<char>());
  } else {
    try {
      const std::string bytes = hal::read_whole_file(capture.path, kMaxCaptureBytes);
      capture.bytes.assign(bytes.begin(), bytes.end());
    } catch (const hal::FileError& error) {
      err << "blockmap: " << error.what() << '\n';
      return false;
    }
  }
  intact = true;
  if (hal::protocol::byte_log::has_magic(capture.bytes)) {
    intact = unpack_byte_log(capture, err);
  } else {
    capture.chunks.push_back({0, capture.bytes.size(), 0});
  }
  return true;
}

}  // namespace

LineIndex::LineIndex(const std::vector<std::uint8_t>& bytes) {
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    if (bytes[i] == '\n') {
      newlines_.push_back(i);
    }
  }
}

std::size_t LineIndex::line_of(std::uint64_t offset) const {
  return 1 + static_cast<std::size_t>(std::lower_bound(newlines_.begin(), newlines_.end(), offset) -
                                      newlines_.begin());
}

void add_time(Json& line, const Capture& capture, TimestampNs stamp_ns) {
  if (capture.timed) {
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
  auto capture = std::make_shared<Capture>();
  std::vector<std::string> names;
  std::string help = "the device protocol:";
  for (const DecoderEntry& entry : kDecoders) {
    names.emplace_back(entry.name);
    help += std::string("\n  ") + entry.name + ": " + entry.description;
  }
  decode->add_option("protocol", *protocol, help)->required()->check(CLI::IsMember(names));
  decode->add_option("file", capture->path, "the capture; - reads standard input")->required();
  return {decode, [protocol, capture](std::ostream& out, std::ostream& err) {
            bool intact = true;
            if (!read_capture(*capture, intact, err)) {
              return kExitFailure;
            }
            for (const DecoderEntry& entry : kDecoders) {
              if (*protocol == entry.name) {
                const int status = entry.decode(*capture, out, err);
                return intact ? status : kExitFailure;
              }
            }
            return kExitUsage;  // unreachable: CLI11 checked the name
          }};
}

}  // namespace blockmap::cli
