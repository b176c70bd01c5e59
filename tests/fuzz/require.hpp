// A promise a fuzz target holds the code to: broken, it ends the run as a crash, which
// libFuzzer reports with the input that broke it.
#pragma once

#include <cstdlib>

namespace blockmap::fuzz {

inline void require(bool condition) {
  if (!condition) {
    std::abort();
  }
}

}  // namespace blockmap::fuzz
