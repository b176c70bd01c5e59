// `blockmap decode scip2`: a Hokuyo SCIP 2.0 byte capture as one JSON object per reply; scans
// with their geometry and ranges (null where the beam has no valid range); damaged replies as
// {"error": reason, "line": N}.
#include <ostream>
#include <span>
#include <string>

#include "blockmap/hal/protocol/hokuyo_scip2.hpp"
#include "cli.hpp"
#include "commands/decoders.hpp"

namespace blockmap::cli {

int decode_scip2(CaptureReader& capture, std::ostream& out, std::ostream& err) {
  namespace scip2 = hal::protocol::hokuyo_scip2;
  LineCounter lines;
  scip2::Decoder decoder;
  std::span<const std::uint8_t> piece;
  TimestampNs stamp_ns = 0;
  std::uint64_t piece_offset = 0;  // of the piece in the stream
  for (; capture.next(piece, stamp_ns); piece_offset += piece.size()) {
    lines.feed(piece);
    std::span<const std::uint8_t> rest = piece;
    while (!rest.empty()) {
      const std::uint64_t offset = piece_offset + piece.size() - rest.size();
      const scip2::Decoder::Step step = decoder.push(rest, stamp_ns);
      rest = rest.subspan(step.consumed);
      Json line;
      if (step.rejected) {
        line["error"] = scip2::to_string(step.reason);
        line["line"] = lines.line_of(offset + step.consumed - 1);
      } else if (step.reply != nullptr) {
        add_time(line, capture, step.scan != nullptr ? step.scan->header.stamp_ns : stamp_ns);
        line["command"] = std::string(step.reply->echo);
        line["status"] = std::string(step.reply->status);
        if (step.scan != nullptr) {
          const msg::LaserScan& scan = *step.scan;
          line["sensor_time_ms"] = scan.scan_counter;
          line["beams"] = scan.beam_count;
          line["start_angle_rad"] = rounded(scan.start_angle_rad, 9);
          line["angle_increment_rad"] = rounded(scan.angle_increment_rad, 9);
          line["ranges_m"] = ranges_json(scan, 3);
        }
      } else {
        continue;
      }
      out << line.dump() << '\n';
    }
  }
  err << "scip2: " << decoder.replies_decoded() << " replies, " << decoder.scans_decoded()
      << " scans";
  print_drops(err, decoder.drops());
  err << '\n';
  return kExitOk;
}

}  // namespace blockmap::cli
