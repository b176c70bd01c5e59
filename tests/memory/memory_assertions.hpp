// GoogleTest assertions for the steady state.
#pragma once

#include <gtest/gtest.h>

#include "allocation_counter.hpp"

// Runs `statement` inside a SteadyStateScope and fails (non-fatally) if it allocated.
#define EXPECT_NO_ALLOCATIONS(statement)                                            \
  do {                                                                              \
    ::blockmap::testing::SteadyStateScope blockmap_steady_scope;                    \
    statement;                                                                      \
    const auto blockmap_allocations = blockmap_steady_scope.allocations();          \
    const auto blockmap_bytes = blockmap_steady_scope.allocated_bytes();            \
    EXPECT_EQ(blockmap_allocations, 0u)                                             \
        << "steady state allocated " << blockmap_bytes << " bytes in: " #statement; \
  } while (false)
