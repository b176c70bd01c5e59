// Build-rule probe (compiled like a file in src/): core headers are reachable.
#include "blockmap/core/ring_buffer.hpp"

namespace blockmap::probe {
int core_probe_capacity();
int core_probe_capacity() {
  return static_cast<int>(RingBuffer<int, 4>{}.capacity());
}
}  // namespace blockmap::probe
