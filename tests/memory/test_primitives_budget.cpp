// The bounded-memory primitives allocate nothing once built: every steady-state operation,
// including the overflow paths (reject, overwrite, pool exhausted), runs under
// EXPECT_NO_ALLOCATIONS. The same tests run on x86-64, aarch64 and armhf.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "allocation_counter.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/core/counter.hpp"
#include "blockmap/core/fixed_pool.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/core/spsc_queue.hpp"
#include "blockmap/hal/sim/manual_clock.hpp"
#include "memory_assertions.hpp"

namespace blockmap {
namespace {

// A message of the size class the pipeline hands around (a few hundred bytes).
struct Message {
  std::int64_t stamp_ns = 0;
  std::uint32_t source_id = 0;
  float ranges_m[64] = {};
};

TEST(PrimitivesBudget, RingBufferSteadyStateIncludingOverflow) {
  RingBuffer<Message, 16> ring;
  Message message;
  EXPECT_NO_ALLOCATIONS({
    for (int i = 0; i < 10'000; ++i) {
      message.stamp_ns = i;
      ring.push_overwrite(message);  // drops the oldest once full
      (void)ring.try_push(message);  // rejected once full
      if (i % 3 == 0) {
        (void)ring.try_pop(message);
      }
    }
  });
  EXPECT_GT(ring.dropped_oldest().value(), 0u);
  EXPECT_GT(ring.rejected_newest().value(), 0u);
}

TEST(PrimitivesBudget, ArenaBackedRingAfterInit) {
  Arena arena(std::size_t{64} * 1024);
  RingBufferRef<Message> ring(arena, 32, "scan history");
  arena.seal();
  Message message;
  EXPECT_NO_ALLOCATIONS({
    for (int i = 0; i < 5'000; ++i) {
      ring.push_overwrite(message);
    }
  });
  EXPECT_EQ(ring.size(), 32u);
}

TEST(PrimitivesBudget, SpscQueueBetweenTwoThreads) {
  SpscQueue<Message, 8> queue;
  constexpr int kMessages = 50'000;
  std::atomic<bool> ready{false};
  std::atomic<bool> go{false};
  std::atomic<int> received{0};
  // The thread is started, and has run, before the steady state begins: starting a thread
  // allocates (its stack, thread-local storage), running it must not.
  std::thread consumer([&] {
    ready.store(true, std::memory_order_release);
    while (!go.load(std::memory_order_acquire)) {
      std::this_thread::yield();
    }
    Message message;
    while (received.load(std::memory_order_relaxed) < kMessages) {
      if (queue.try_pop(message)) {
        received.fetch_add(1, std::memory_order_relaxed);
      } else {
        std::this_thread::yield();  // both cores may be busy with other tests
      }
    }
  });

  while (!ready.load(std::memory_order_acquire)) {
    std::this_thread::yield();
  }
  {
    testing::SteadyStateScope steady;
    go.store(true, std::memory_order_release);
    Message message;
    for (int sent = 0; sent < kMessages;) {
      message.stamp_ns = sent;
      if (queue.try_push(message)) {
        ++sent;
      } else {
        std::this_thread::yield();
      }
    }
    while (received.load(std::memory_order_relaxed) < kMessages) {
      std::this_thread::yield();
    }
    EXPECT_EQ(steady.allocations(), 0u)
        << "both threads together allocated " << steady.allocated_bytes() << " bytes";
  }
  consumer.join();
  EXPECT_GT(queue.rejected_newest().value(), 0u) << "the small queue should have filled up";
}

TEST(PrimitivesBudget, FixedPoolCreateReleaseAndExhaustion) {
  FixedPool<Message, 4> pool;
  Message* held[4] = {};
  EXPECT_NO_ALLOCATIONS({
    for (int round = 0; round < 1'000; ++round) {
      for (auto*& slot : held) {
        slot = pool.try_create();
      }
      (void)pool.try_create();  // exhausted: counted, not allocated
      for (auto* slot : held) {
        pool.release(slot);
      }
    }
  });
  EXPECT_EQ(pool.exhausted().value(), 1'000u);
}

TEST(PrimitivesBudget, ArenaServesInitWithoutTouchingTheHeap) {
  Arena arena(1 << 20);  // the one heap allocation
  EXPECT_NO_ALLOCATIONS({
    auto voxels = arena.allocate_array<float>(10'000, "voxel window");
    auto particles = arena.allocate_array<double>(std::size_t{3} * 1'000, "particle filter");
    RingBufferRef<Message> scans(arena, 8, "scan queue");
    FixedPoolRef<Message> patches(arena, 16, "plane patches");
    testing::escape(voxels.data());
    testing::escape(particles.data());
  });
  EXPECT_EQ(arena.owners().size(), 4u);
}

TEST(PrimitivesBudget, ArenaCapIsEnforced) {
  // The budget is a cap, not a hint: what does not fit is refused and counted, and the heap
  // is not asked instead.
  Arena arena(4096);
  EXPECT_NO_ALLOCATIONS({
    for (int i = 0; i < 100; ++i) {
      (void)arena.try_allocate(100, 8, "greedy");
    }
  });
  EXPECT_LE(arena.used_bytes(), arena.budget_bytes());
  EXPECT_GT(arena.failed_allocations().value(), 0u);
}

TEST(PrimitivesBudget, CountersAndClocksDoNotAllocate) {
  MonotonicCounter counter;
  hal::sim::ManualClock clock;
  EXPECT_NO_ALLOCATIONS({
    for (int i = 0; i < 10'000; ++i) {
      counter.increment();
      (void)clock.advance_ns(1'000);
    }
  });
  EXPECT_EQ(counter.value(), 10'000u);
}

// Bookkeeping budgets, per architecture: the views stay small on 32- and 64-bit targets.
TEST(PrimitivesBudget, BookkeepingFitsItsBudget) {
  EXPECT_LE(sizeof(RingBufferRef<Message>), 64u);
  EXPECT_LE(sizeof(FixedPoolRef<Message>), 96u);
  EXPECT_LE(sizeof(SpscQueueRef<Message>), 3 * kCacheLineBytes);
  RingBuffer<Message, 10> ring;
  EXPECT_EQ(ring.memory_bytes(), 10 * sizeof(Message) + sizeof(RingBufferRef<Message>));
  SpscQueue<Message, 10> queue;
  EXPECT_EQ(queue.memory_bytes(), 11 * sizeof(Message) + sizeof(SpscQueueRef<Message>));
}

}  // namespace
}  // namespace blockmap
