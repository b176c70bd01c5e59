#include "blockmap/core/merge_in_place.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "throwing_check.hpp"

namespace blockmap {
namespace {

// Random sorted fronts and backs, with room from exactly enough to plenty: the merge is the
// sort of both.
TEST(MergeInPlace, MergesTheBackIntoTheFrontAsASortWould) {
  std::mt19937 random(11);
  std::uniform_int_distribution<int> value(0, 50);  // repeats: equal keys across the two
  for (int round = 0; round < 200; ++round) {
    const auto front = static_cast<std::size_t>(round % 17);
    const auto back = static_cast<std::size_t>((round / 17) % 9);
    const std::size_t size = front + 2 * back + static_cast<std::size_t>(round % 3);
    std::vector<int> array(size, -1);
    for (std::size_t i = 0; i < front; ++i) {
      array[i] = value(random);
    }
    for (std::size_t i = size - back; i < size; ++i) {
      array[i] = value(random);
    }
    std::sort(array.begin(), array.begin() + static_cast<std::ptrdiff_t>(front));
    std::sort(array.end() - static_cast<std::ptrdiff_t>(back), array.end());
    std::vector<int> expected(array.begin(), array.begin() + static_cast<std::ptrdiff_t>(front));
    expected.insert(expected.end(), array.end() - static_cast<std::ptrdiff_t>(back), array.end());
    std::sort(expected.begin(), expected.end());

    merge_back_into_front(std::span<int>(array), front, back, std::less<>());
    EXPECT_EQ(
        std::vector<int>(array.begin(), array.begin() + static_cast<std::ptrdiff_t>(front + back)),
        expected)
        << "front " << front << ", back " << back << ", size " << size;
  }
}

TEST(MergeInPlace, RefusesTooLittleRoom) {
  const testing::ThrowOnCheckFailure throwing;
  std::vector<int> array = {1, 2, 3, 0, 4};  // three in front, two at the back: room for one
  EXPECT_THROW(merge_back_into_front(std::span<int>(array), 3, 2, std::less<>()),
               testing::CheckFailedError);
}

}  // namespace
}  // namespace blockmap
