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

int decode_scip2(const Capture& capture, std::ostream& out, std::ostream& err) {
  namespace scip2 = hal::protocol::hokuyo_scip2;
  const LineIndex lines(capture.bytes);
  scip2::Decoder decoder;
  for (const Chunk& chunk : capture.chunks) {
    std::span<const std::uint8_t> rest(capture.bytes.data() + chunk.offset, chunk.length);
    while (!rest.empty()) {
      const std::size_t offset = chunk.offset + chunk.length - rest.size();
      const scip2::Decoder::Step step = decoder.push(rest, chunk.stamp_ns);
      rest = rest.subspan(step.consumed);
      Json line;
      if (step.rejected) {
        line["error"] = scip2::to_string(step.reason);
        line["line"] = lines.line_of(offset + step.consumed - 1);
      } else if (step.reply != nullptr) {
        add_time(line, capture, step.scan != nullptr ? step.scan->header.stamp_ns : chunk.stamp_ns);
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
