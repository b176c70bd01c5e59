// Costs of the bounded-memory primitives that sit on every message's path.
//   build/release/tests/bench/bench_core
#include <benchmark/benchmark.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "blockmap/core/fixed_pool.hpp"
#include "blockmap/core/ring_buffer.hpp"
#include "blockmap/core/spsc_queue.hpp"

namespace blockmap {
namespace {

// The size of an odometry or GPS message: a stamp, a source and a handful of doubles.
struct SmallMessage {
  std::int64_t stamp_ns = 0;
  std::uint32_t source_id = 0;
  double values[6] = {};
};

void BM_RingBufferPushOverwrite(benchmark::State& state) {
  RingBuffer<SmallMessage, 1024> ring;
  SmallMessage message;
  for (auto _ : state) {
    ++message.stamp_ns;
    ring.push_overwrite(message);
    benchmark::DoNotOptimize(ring.back());
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RingBufferPushOverwrite);

void BM_SpscQueueSameThreadRoundTrip(benchmark::State& state) {
  SpscQueue<SmallMessage, 1024> queue;
  SmallMessage message;
  for (auto _ : state) {
    ++message.stamp_ns;
    benchmark::DoNotOptimize(queue.try_push(message));
    benchmark::DoNotOptimize(queue.try_pop(message));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SpscQueueSameThreadRoundTrip);

// Throughput between two threads: the producer is timed, a consumer thread drains.
void BM_SpscQueueTwoThreads(benchmark::State& state) {
  SpscQueue<SmallMessage, 1024> queue;
  std::atomic<bool> stop{false};
  std::thread consumer([&] {
    SmallMessage sink;
    while (!stop.load(std::memory_order_relaxed)) {
      while (queue.try_pop(sink)) {
      }
    }
  });
  SmallMessage message;
  for (auto _ : state) {
    ++message.stamp_ns;
    while (!queue.try_push(message)) {
    }
  }
  stop.store(true);
  consumer.join();
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SpscQueueTwoThreads)->UseRealTime();

void BM_FixedPoolCreateRelease(benchmark::State& state) {
  FixedPool<SmallMessage, 256> pool;
  for (auto _ : state) {
    SmallMessage* message = pool.try_create();
    benchmark::DoNotOptimize(message);
    pool.release(message);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FixedPoolCreateRelease);

}  // namespace
}  // namespace blockmap
