#include "blockmap/core/arena.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>

#include "throwing_check.hpp"

namespace blockmap {
namespace {

bool is_aligned(const void* pointer, std::size_t alignment) {
  return reinterpret_cast<std::uintptr_t>(pointer) % alignment == 0;
}

TEST(Arena, ServesAlignedBlocksAndChargesOwners) {
  Arena arena(1024);
  void* a = arena.allocate(3, 1, "a");
  void* b = arena.allocate(8, 8, "b");
  void* c = arena.allocate(64, 64, "c");
  EXPECT_TRUE(is_aligned(b, 8));
  EXPECT_TRUE(is_aligned(c, 64));
  EXPECT_NE(a, b);
  ASSERT_EQ(arena.owners().size(), 3u);
  std::size_t charged = 0;
  for (const auto& line : arena.owners()) {
    charged += line.bytes;
  }
  EXPECT_EQ(charged, arena.used_bytes());
  EXPECT_EQ(arena.used_bytes() + arena.remaining_bytes(), arena.budget_bytes());
}

TEST(Arena, SumsRepeatedOwnersIntoOneLine) {
  Arena arena(256);
  (void)arena.allocate(16, 8, "voxel window");
  (void)arena.allocate(16, 8, "voxel window");
  ASSERT_EQ(arena.owners().size(), 1u);
  EXPECT_EQ(arena.owners()[0].bytes, 32u);
}

TEST(Arena, RefusesBeyondItsBudgetAndCountsIt) {
  Arena arena(100);
  EXPECT_NE(arena.try_allocate(60, 4, "first"), nullptr);
  EXPECT_EQ(arena.try_allocate(60, 4, "second"), nullptr);
  EXPECT_EQ(arena.failed_allocations().value(), 1u);
  EXPECT_NE(arena.try_allocate(40, 4, "third"), nullptr);
  EXPECT_EQ(arena.remaining_bytes(), 0u);
}

TEST(Arena, OverBudgetAllocateIsACheckFailure) {
  testing::ThrowOnCheckFailure throw_on_check;
  Arena arena(64);
  EXPECT_THROW((void)arena.allocate(65, 1, "too big"), testing::CheckFailedError);
  EXPECT_THROW((void)arena.allocate_array<std::uint64_t>(9, "too many"), testing::CheckFailedError);
}

TEST(Arena, AllocatingAfterSealIsACheckFailure) {
  testing::ThrowOnCheckFailure throw_on_check;
  Arena arena(64);
  (void)arena.allocate(8, 8, "init");
  arena.seal();
  EXPECT_TRUE(arena.sealed());
  EXPECT_THROW((void)arena.try_allocate(8, 8, "steady state"), testing::CheckFailedError);
}

TEST(Arena, ArraysAreValueInitialised) {
  Arena arena(256);
  auto values = arena.allocate_array<double>(8, "values");
  ASSERT_EQ(values.size(), 8u);
  for (double value : values) {
    EXPECT_EQ(value, 0.0);
  }
}

TEST(Arena, ServesFromCallerStorage) {
  alignas(64) std::array<std::byte, 128> storage{};
  Arena arena{std::span<std::byte>(storage)};
  void* block = arena.allocate(32, 16, "static");
  EXPECT_EQ(block, storage.data());
  EXPECT_EQ(arena.budget_bytes(), 128u);
}

TEST(Arena, BadAlignmentIsACheckFailure) {
  testing::ThrowOnCheckFailure throw_on_check;
  Arena arena(64);
  EXPECT_THROW((void)arena.try_allocate(8, 3, "odd"), testing::CheckFailedError);
}

TEST(Arena, FoldsOwnersBeyondTheLedgerIntoOneLine) {
  Arena arena(4096);
  static std::array<std::array<char, 8>, Arena::kMaxOwners + 5> names{};
  for (std::size_t i = 0; i < names.size(); ++i) {
    names[i] = {'o', static_cast<char>('A' + i % 26), static_cast<char>('a' + i / 26), '\0'};
    (void)arena.allocate(8, 8, names[i].data());
  }
  EXPECT_EQ(arena.owners().size(), Arena::kMaxOwners);
  EXPECT_STREQ(arena.owners().back().owner, "(other owners)");
  std::size_t charged = 0;
  for (const auto& line : arena.owners()) {
    charged += line.bytes;
  }
  EXPECT_EQ(charged, arena.used_bytes());
}

}  // namespace
}  // namespace blockmap
