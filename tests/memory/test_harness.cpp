// The harness's own tests: a steady-state loop that allocates must be caught, by every route
// an allocation can take (new, new[], malloc, calloc, realloc, aligned new, standard
// containers, Eigen). If these pass while counting is broken, every budget test would be
// meaningless, so they come first.
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "allocation_counter.hpp"
#include "memory_assertions.hpp"

namespace blockmap::testing {
namespace {

TEST(AllocationHarness, CountingIsActiveInThisBinary) {
  EXPECT_TRUE(allocation_counting_active());
}

TEST(AllocationHarness, CatchesNewInASteadyStateLoop) {
  SteadyStateScope steady;
  for (int i = 0; i < 100; ++i) {
    int* leak_free = new int(i);
    escape(leak_free);
    delete leak_free;
  }
  EXPECT_EQ(steady.allocations(), 100u);
  EXPECT_GE(steady.allocated_bytes(), 100 * sizeof(int));
}

TEST(AllocationHarness, CatchesArrayAndAlignedNew) {
  struct alignas(64) CacheLine {
    char bytes[64];
  };
  SteadyStateScope steady;
  auto* array = new double[16];
  escape(array);
  delete[] array;
  auto* line = new CacheLine();
  escape(line);
  delete line;
  EXPECT_EQ(steady.allocations(), 2u);
}

TEST(AllocationHarness, CatchesMallocCallocAndRealloc) {
  SteadyStateScope steady;
  void* block = std::malloc(32);
  escape(block);
  block = std::realloc(block, 4096);
  escape(block);
  std::free(block);
  void* zeroed = std::calloc(4, 8);
  escape(zeroed);
  std::free(zeroed);
  EXPECT_EQ(steady.allocations(), 3u);
}

TEST(AllocationHarness, CatchesContainerGrowth) {
  SteadyStateScope steady;
  std::vector<int> grows;
  for (int i = 0; i < 10; ++i) {
    grows.push_back(i);  // NOLINT(performance-inefficient-vector-operation): the point
  }
  escape(grows.data());
  EXPECT_GT(steady.allocations(), 0u);
}

TEST(AllocationHarness, ExpectNoAllocationsFailsWhenTheLoopAllocates) {
  // The assertion used by every budget test must itself fail on an allocating loop.
  EXPECT_NONFATAL_FAILURE(EXPECT_NO_ALLOCATIONS({
                            for (int i = 0; i < 3; ++i) {
                              auto owned = std::make_unique<long>(i);
                              ::blockmap::testing::escape(owned.get());
                            }
                          }),
                          "steady state allocated");
}

TEST(AllocationHarness, ExpectNoAllocationsPassesWhenTheLoopDoesNotAllocate) {
  int sum = 0;
  EXPECT_NO_ALLOCATIONS({
    for (int i = 0; i < 1000; ++i) {
      sum += i;
    }
  });
  EXPECT_EQ(sum, 499500);
}

TEST(AllocationHarness, TurnsOnEigensNoMallocModeOnlyInsideTheScope) {
  EXPECT_TRUE(Eigen::internal::is_malloc_allowed());
  {
    SteadyStateScope steady;
    EXPECT_FALSE(Eigen::internal::is_malloc_allowed());
  }
  EXPECT_TRUE(Eigen::internal::is_malloc_allowed());
}

TEST(AllocationHarness, FixedSizeEigenMathDoesNotAllocate) {
  const Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity() * 2.0;
  Eigen::Vector3d point(1.0, 2.0, 3.0);
  EXPECT_NO_ALLOCATIONS({
    for (int i = 0; i < 100; ++i) {
      point = rotation * point * 0.5;
    }
  });
  EXPECT_DOUBLE_EQ(point.z(), 3.0);
}

#if defined(NDEBUG)
TEST(AllocationHarness, CatchesADynamicEigenMatrix) {
  // With assertions compiled out Eigen's no-malloc mode cannot stop the program, so the
  // counter is what catches the allocation.
  SteadyStateScope steady;
  Eigen::MatrixXd dynamic(8, 8);
  escape(dynamic.data());
  EXPECT_GT(steady.allocations(), 0u);
}
#else
TEST(AllocationHarnessDeathTest, EigensNoMallocModeStopsADynamicMatrix) {
  // "fast" forks without exec: QEMU user mode cannot exec a foreign binary.
  GTEST_FLAG_SET(death_test_style, "fast");
  EXPECT_DEATH(
      {
        SteadyStateScope steady;
        Eigen::MatrixXd dynamic(8, 8);
        escape(dynamic.data());
      },
      "heap allocation is forbidden");
}
#endif

}  // namespace
}  // namespace blockmap::testing
