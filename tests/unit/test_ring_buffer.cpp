#include "blockmap/core/ring_buffer.hpp"

#include <gtest/gtest.h>

#include <array>

#include "throwing_check.hpp"

namespace blockmap {
namespace {

TEST(RingBuffer, StartsEmptyWithItsCapacity) {
  RingBuffer<int, 3> ring;
  EXPECT_EQ(ring.capacity(), 3u);
  EXPECT_EQ(ring.size(), 0u);
  EXPECT_TRUE(ring.empty());
  EXPECT_FALSE(ring.full());
}

TEST(RingBuffer, KeepsFifoOrderAcrossTheWrap) {
  RingBuffer<int, 3> ring;
  int out = 0;
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(ring.try_push(i));
    ASSERT_TRUE(ring.try_pop(out));
    EXPECT_EQ(out, i);
  }
  EXPECT_FALSE(ring.try_pop(out));
}

TEST(RingBuffer, TryPushRejectsTheNewestWhenFullAndCountsIt) {
  RingBuffer<int, 2> ring;
  EXPECT_TRUE(ring.try_push(1));
  EXPECT_TRUE(ring.try_push(2));
  EXPECT_FALSE(ring.try_push(3));
  EXPECT_FALSE(ring.try_push(4));
  EXPECT_EQ(ring.rejected_newest().value(), 2u);
  EXPECT_EQ(ring.dropped_oldest().value(), 0u);
  EXPECT_EQ(ring.front(), 1);
  EXPECT_EQ(ring.back(), 2);
}

TEST(RingBuffer, PushOverwriteDropsTheOldestWhenFullAndCountsIt) {
  RingBuffer<int, 3> ring;
  for (int i = 1; i <= 5; ++i) {
    ring.push_overwrite(i);
  }
  EXPECT_EQ(ring.size(), 3u);
  EXPECT_EQ(ring.dropped_oldest().value(), 2u);
  EXPECT_EQ(ring[0], 3);
  EXPECT_EQ(ring[1], 4);
  EXPECT_EQ(ring[2], 5);
}

TEST(RingBuffer, IndexCountsFromTheOldestAfterWrapping) {
  RingBuffer<int, 4> ring;
  for (int i = 0; i < 6; ++i) {
    ring.push_overwrite(i);
  }
  ring.pop_front();
  ASSERT_EQ(ring.size(), 3u);
  EXPECT_EQ(ring.front(), 3);
  EXPECT_EQ(ring[1], 4);
  EXPECT_EQ(ring.back(), 5);
}

TEST(RingBuffer, ClearForgetsEverythingButKeepsCapacity) {
  RingBuffer<int, 2> ring;
  ring.push_overwrite(7);
  ring.clear();
  EXPECT_TRUE(ring.empty());
  EXPECT_EQ(ring.capacity(), 2u);
  EXPECT_TRUE(ring.try_push(8));
  EXPECT_EQ(ring.front(), 8);
}

TEST(RingBuffer, SizeErasedViewWorksOverExternalStorage) {
  std::array<double, 5> storage{};
  RingBufferRef<double> view{std::span<double>(storage)};
  view.push_overwrite(1.5);
  EXPECT_EQ(storage[0], 1.5);
  EXPECT_EQ(view.capacity(), 5u);
}

TEST(RingBuffer, PassesAsItsSizeErasedView) {
  RingBuffer<int, 8> ring;
  auto fill = [](RingBufferRef<int>& any_ring) {
    for (int i = 0; i < 3; ++i) {
      any_ring.push_overwrite(i);
    }
  };
  fill(ring);
  EXPECT_EQ(ring.size(), 3u);
}

TEST(RingBuffer, TakesItsCapacityFromTheArena) {
  Arena arena(1024);
  RingBufferRef<std::uint32_t> ring(arena, 16, "test ring");
  EXPECT_EQ(ring.capacity(), 16u);
  EXPECT_EQ(arena.used_bytes(), 16 * sizeof(std::uint32_t));
  ring.push_overwrite(42);
  EXPECT_EQ(ring.front(), 42u);
}

TEST(RingBuffer, AMemberTakesItsCapacityFromTheArenaAtInit) {
  Arena arena(1024);
  RingBufferRef<int> ring;  // as a member whose capacity comes from configuration
  ring.init(arena, 3, "test.ring");
  EXPECT_EQ(ring.capacity(), 3u);
  for (int value = 1; value <= 4; ++value) {
    ring.push_overwrite(value);
  }
  EXPECT_EQ(ring[0], 2);
  EXPECT_EQ(ring.back(), 4);
  EXPECT_EQ(ring.dropped_oldest().value(), 1u);
  EXPECT_EQ(arena.used_bytes(), 3 * sizeof(int));
}

TEST(RingBuffer, ReportsElementStoragePlusBookkeeping) {
  RingBuffer<std::uint64_t, 100> ring;
  EXPECT_EQ(ring.memory_bytes(),
            100 * sizeof(std::uint64_t) + sizeof(RingBufferRef<std::uint64_t>));
  EXPECT_LE(ring.memory_bytes(), sizeof(ring));
}

TEST(RingBuffer, OutOfRangeAccessIsACheckFailure) {
  testing::ThrowOnCheckFailure throw_on_check;
  RingBuffer<int, 2> ring;
  EXPECT_THROW((void)ring.front(), testing::CheckFailedError);
  EXPECT_THROW(ring.pop_front(), testing::CheckFailedError);
  ring.push_overwrite(1);
  EXPECT_THROW((void)ring[1], testing::CheckFailedError);
}

TEST(RingBuffer, ZeroCapacityViewIsACheckFailure) {
  testing::ThrowOnCheckFailure throw_on_check;
  EXPECT_THROW(RingBufferRef<int>{std::span<int>()}, testing::CheckFailedError);
}

}  // namespace
}  // namespace blockmap
