#include "blockmap/core/check.hpp"

#include <gtest/gtest.h>

#include <string>

#include "throwing_check.hpp"

namespace blockmap {
namespace {

int g_calls = 0;
std::string g_last_message;

[[noreturn]] void recording_handler(const CheckFailure& failure) {
  ++g_calls;
  g_last_message = failure.message;
  throw testing::CheckFailedError(failure);
}

TEST(Check, PassingCheckDoesNothing) {
  const CheckHandler previous = set_check_handler(&recording_handler);
  g_calls = 0;
  BLOCKMAP_CHECK(1 + 1 == 2);
  set_check_handler(previous);
  EXPECT_EQ(g_calls, 0);
}

TEST(Check, FailingCheckRunsTheInstalledHandlerWithTheReason) {
  const CheckHandler previous = set_check_handler(&recording_handler);
  g_calls = 0;
  EXPECT_THROW(BLOCKMAP_CHECK_MSG(false, "queue depth must be positive"),
               testing::CheckFailedError);
  set_check_handler(previous);
  EXPECT_EQ(g_calls, 1);
  EXPECT_EQ(g_last_message, "queue depth must be positive");
}

TEST(Check, SetReturnsThePreviousHandler) {
  const CheckHandler original = set_check_handler(&recording_handler);
  EXPECT_EQ(set_check_handler(original), &recording_handler);
}

TEST(CheckDeathTest, DefaultHandlerPrintsOneLineAndAborts) {
  // "fast" forks without exec: QEMU user mode cannot exec a foreign binary.
  GTEST_FLAG_SET(death_test_style, "fast");
  EXPECT_DEATH(BLOCKMAP_CHECK_MSG(2 < 1, "two is not less than one"),
               "CHECK failed at .*test_check.cpp:[0-9]+ .*2 < 1 \\(two is not less than one\\)");
}

TEST(CheckDeathTest, AbortsEvenWhenAHandlerReturns) {
  // "fast" forks without exec: QEMU user mode cannot exec a foreign binary.
  GTEST_FLAG_SET(death_test_style, "fast");
  // A handler that breaks its contract by returning: the default handler still stops the
  // program, so a failed CHECK can never fall through into the code it guards.
  EXPECT_DEATH(
      {
        set_check_handler([](const CheckFailure&) {});
        BLOCKMAP_CHECK(false);
      },
      "CHECK failed");
}

}  // namespace
}  // namespace blockmap
