// Planes as JSON: the plane list's entries (docs/formats.md, plane list) and the plane stream's
// updates, one JSON object per line of planes.jsonl (docs/formats.md, run outputs), the text
// twin of the binary plane stream (hal/protocol/plane_stream.hpp, docs/log-formats.md).
#pragma once

#include <vector>

#include <span>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "blockmap/core/time.hpp"
#include "blockmap/hal/protocol/plane_stream.hpp"
#include "blockmap/msg/plane_patch.hpp"

namespace blockmap::cli {

// `value` to a multiple of `unit` (1e-4 m, 1e-6 for directions): what the numbers mean, no
// more; it prints short.
[[nodiscard]] double rounded_to(double value, double unit);

// One plane of the list; positions moved by origin_m (a detector that worked relative to a
// cloud's origin reports in the file's frame).
[[nodiscard]] nlohmann::json plane_json(const msg::PlanePatch& plane,
                                        const Eigen::Vector3d& origin_m = Eigen::Vector3d::Zero());

// The planes of a plane list, as `blockmap planes` and `run` write it. Every mistake
// throws std::invalid_argument naming the entry and key ("planes[3].normal: must be 3
// numbers"); a polygon longer than msg::kMaxPolygonVertices keeps its convex outline's first
// vertices only when it is no longer than that, else is refused.
[[nodiscard]] std::vector<msg::PlanePatch> planes_from_json(const nlohmann::json& document);

// One update: {"t_s": seconds, "added": [planes], "changed": [planes], "finalized": [planes],
// "removed": [planes]},
// every key present (an empty list when nothing changed that way).
[[nodiscard]] nlohmann::json plane_update_json(
    TimestampNs stamp_ns, std::span<const hal::protocol::plane_stream::PlaneChange> changes);

}  // namespace blockmap::cli
