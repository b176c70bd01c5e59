// CHECK: the first of the three tiers of failure (see docs/formats.md, "Failures").
//
//   a bug (a broken invariant)      BLOCKMAP_CHECK        -> the check handler, never returns
//   an expected I/O outcome         IoStatus (status.hpp) -> returned, [[nodiscard]]
//   a non-fatal fault               MonotonicCounter      -> counted, read by health reporting
//
// CHECKs stay on in release builds: each costs one predictable branch. The handler is
// replaceable (for example to log to a flight recorder before resetting, or to throw in a test);
// if a handler returns, the default handler runs, which prints one line to stderr and aborts.
#pragma once

namespace blockmap {

struct CheckFailure {
  const char* condition;  // the source text of the failed condition
  const char* message;    // why it matters; never null
  const char* file;
  int line;
  const char* function;
};

// A handler must not return normally (it may throw or terminate). Thread-safe to call.
using CheckHandler = void (*)(const CheckFailure& failure);

// Installs `handler` (nullptr restores the default) and returns the previous one.
CheckHandler set_check_handler(CheckHandler handler) noexcept;

// Called by the macros below; runs the installed handler, then the default one.
[[noreturn]] void check_failed(const CheckFailure& failure);

}  // namespace blockmap

#define BLOCKMAP_CHECK_MSG(condition, message)                                            \
  do {                                                                                    \
    if (!(condition)) [[unlikely]] {                                                      \
      ::blockmap::check_failed(                                                           \
          ::blockmap::CheckFailure{#condition, (message), __FILE__, __LINE__, __func__}); \
    }                                                                                     \
  } while (false)

#define BLOCKMAP_CHECK(condition) BLOCKMAP_CHECK_MSG(condition, "invariant violated")
