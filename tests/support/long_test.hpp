// Tests that drive a whole run through the pipeline (tens of seconds of data through the CLI,
// the daemon, the mapper or the filter) take 12 to 60 s each under QEMU, and together two thirds
// of an emulated tree's test time. They run on the host trees (sanitized, and the worlds tree);
// the cross trees skip them, and run every other test, the memory tier included, so that
// scripts/test keeps to its time (docs/README.md, "What scripts/test does, and why it is
// arranged so"). Write BLOCKMAP_LONG_TEST(); first in such a test.
#pragma once

#include <gtest/gtest.h>

#if defined(BLOCKMAP_LONG_TESTS_ELSEWHERE)
#define BLOCKMAP_LONG_TEST() GTEST_SKIP() << "a whole run: the host trees run it"
#else
#define BLOCKMAP_LONG_TEST() static_cast<void>(0)
#endif
