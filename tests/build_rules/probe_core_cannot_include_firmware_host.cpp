// Build-rule probe (compiled like a file in src/): the composition root's headers must not be
// reachable, so this file must fail to compile.
#include "cli.hpp"
