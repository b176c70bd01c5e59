#include "blockmap/core/fixed_pool.hpp"

#include <gtest/gtest.h>

#include <set>

#include "throwing_check.hpp"

namespace blockmap {
namespace {

struct Tracked {
  explicit Tracked(int value_in, int* alive_in) : value(value_in), alive(alive_in) { ++*alive; }
  ~Tracked() { --*alive; }
  Tracked(const Tracked&) = delete;
  Tracked& operator=(const Tracked&) = delete;
  int value;
  int* alive;
};

TEST(FixedPool, CreatesUntilFullThenRejectsAndCounts) {
  int alive = 0;
  FixedPool<Tracked, 3> pool;
  std::set<Tracked*> handed_out;
  for (int i = 0; i < 3; ++i) {
    Tracked* object = pool.try_create(i, &alive);
    ASSERT_NE(object, nullptr);
    EXPECT_EQ(object->value, i);
    handed_out.insert(object);
  }
  EXPECT_EQ(handed_out.size(), 3u);
  EXPECT_EQ(alive, 3);
  EXPECT_EQ(pool.try_create(9, &alive), nullptr);
  EXPECT_EQ(pool.exhausted().value(), 1u);
  EXPECT_EQ(pool.in_use(), 3u);
  EXPECT_EQ(pool.available(), 0u);
}

TEST(FixedPool, ReleaseDestroysAndReusesTheSlot) {
  int alive = 0;
  FixedPool<Tracked, 2> pool;
  Tracked* first = pool.try_create(1, &alive);
  ASSERT_NE(first, nullptr);
  pool.release(first);
  EXPECT_EQ(alive, 0);
  Tracked* again = pool.try_create(2, &alive);
  EXPECT_EQ(again, first);
  EXPECT_EQ(again->value, 2);
}

TEST(FixedPool, DestroysObjectsStillAliveWithThePool) {
  int alive = 0;
  {
    FixedPool<Tracked, 4> pool;
    (void)pool.try_create(1, &alive);
    (void)pool.try_create(2, &alive);
    EXPECT_EQ(alive, 2);
  }
  EXPECT_EQ(alive, 0);
}

TEST(FixedPool, DoubleReleaseIsACheckFailure) {
  testing::ThrowOnCheckFailure throw_on_check;
  FixedPool<int, 2> pool;
  int* object = pool.try_create(5);
  pool.release(object);
  EXPECT_THROW(pool.release(object), testing::CheckFailedError);
}

TEST(FixedPool, ForeignPointerIsACheckFailure) {
  testing::ThrowOnCheckFailure throw_on_check;
  FixedPool<int, 2> pool;
  int outsider = 0;
  EXPECT_THROW(pool.release(&outsider), testing::CheckFailedError);
}

TEST(FixedPool, TakesItsCapacityFromTheArena) {
  Arena arena(4096);
  FixedPoolRef<double> pool(arena, 10, "test pool");
  EXPECT_EQ(pool.capacity(), 10u);
  EXPECT_GE(arena.used_bytes(), 10 * sizeof(double));
  ASSERT_EQ(arena.owners().size(), 1u);
  EXPECT_STREQ(arena.owners()[0].owner, "test pool");
  EXPECT_EQ(arena.owners()[0].bytes, arena.used_bytes());
  EXPECT_NE(pool.try_create(1.0), nullptr);
}

}  // namespace
}  // namespace blockmap
