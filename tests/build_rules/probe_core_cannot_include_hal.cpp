// Build-rule probe (compiled like a file in src/): a HAL header must not be reachable, so this
// file must fail to compile. tests/build_rules/CMakeLists.txt checks that it does.
#include "blockmap/hal/clock.hpp"
