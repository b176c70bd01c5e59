#include "blockmap/core/spsc_queue.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

#include "throwing_check.hpp"

namespace blockmap {
namespace {

TEST(SpscQueue, HoldsExactlyItsCapacity) {
  SpscQueue<int, 3> queue;
  EXPECT_EQ(queue.capacity(), 3u);
  EXPECT_TRUE(queue.try_push(1));
  EXPECT_TRUE(queue.try_push(2));
  EXPECT_TRUE(queue.try_push(3));
  EXPECT_FALSE(queue.try_push(4));
  EXPECT_EQ(queue.size_approx(), 3u);
  EXPECT_EQ(queue.rejected_newest().value(), 1u);
}

TEST(SpscQueue, PopsInOrderAcrossTheWrap) {
  SpscQueue<int, 2> queue;
  int out = -1;
  for (int i = 0; i < 7; ++i) {
    ASSERT_TRUE(queue.try_push(i));
    ASSERT_TRUE(queue.try_pop(out));
    EXPECT_EQ(out, i);
  }
  EXPECT_FALSE(queue.try_pop(out));
  EXPECT_EQ(queue.size_approx(), 0u);
}

TEST(SpscQueue, RejectionKeepsEverythingAlreadyAccepted) {
  SpscQueue<int, 2> queue;
  ASSERT_TRUE(queue.try_push(10));
  ASSERT_TRUE(queue.try_push(11));
  ASSERT_FALSE(queue.try_push(12));
  int out = 0;
  ASSERT_TRUE(queue.try_pop(out));
  EXPECT_EQ(out, 10);
  ASSERT_TRUE(queue.try_pop(out));
  EXPECT_EQ(out, 11);
}

TEST(SpscQueue, TakesItsCapacityFromTheArena) {
  Arena arena(4096);
  SpscQueueRef<std::uint64_t> queue(arena, 8, "test queue");
  EXPECT_EQ(queue.capacity(), 8u);
  EXPECT_EQ(arena.used_bytes(), 9 * sizeof(std::uint64_t));
}

TEST(SpscQueue, ViewNeedsTwoSlots) {
  testing::ThrowOnCheckFailure throw_on_check;
  std::array<int, 1> one{};
  EXPECT_THROW(SpscQueueRef<int>{std::span<int>(one)}, testing::CheckFailedError);
}

// Two threads, a small queue so that both sides wrap and meet the full and empty states
// often: every message arrives once, in order, whatever the interleaving.
TEST(SpscQueue, DeliversEveryMessageInOrderBetweenTwoThreads) {
  constexpr std::uint64_t kMessages = 200'000;
  SpscQueue<std::uint64_t, 7> queue;
  std::atomic<bool> consumer_ok{true};

  std::thread consumer([&] {
    std::uint64_t expected = 0;
    std::uint64_t value = 0;
    while (expected < kMessages) {
      if (queue.try_pop(value)) {
        if (value != expected) {
          consumer_ok.store(false);
          return;
        }
        ++expected;
      } else {
        std::this_thread::yield();
      }
    }
  });
  for (std::uint64_t i = 0; i < kMessages;) {
    if (queue.try_push(i)) {
      ++i;
    } else {
      std::this_thread::yield();
    }
  }
  consumer.join();
  EXPECT_TRUE(consumer_ok.load());
  EXPECT_EQ(queue.size_approx(), 0u);
}

TEST(SpscQueue, KeepsProducerAndConsumerIndicesOnSeparateCacheLines) {
  EXPECT_GE(alignof(SpscQueueRef<int>), kCacheLineBytes);
  EXPECT_GE(sizeof(SpscQueueRef<int>), 2 * kCacheLineBytes);
}

}  // namespace
}  // namespace blockmap
