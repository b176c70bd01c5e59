// Footprints against truth: the intersection over union of two simple polygons, as
// `blockmap score` computes it (hal/sim/truth_score.hpp).
#pragma once

#include "blockmap/hal/sim/truth_score.hpp"

namespace blockmap::testing {

using hal::sim::footprint_iou;

}  // namespace blockmap::testing
