#include "blockmap/core/check.hpp"

#include <atomic>
#include <cstdio>
#include <cstdlib>

namespace blockmap {
namespace {

std::atomic<CheckHandler> g_check_handler{nullptr};

[[noreturn]] void default_check_handler(const CheckFailure& failure) {
  // One line, so that it survives log rotation and grep: where, what, why.
  std::fprintf(stderr, "blockmap: CHECK failed at %s:%d in %s: %s (%s)\n", failure.file,
               failure.line, failure.function, failure.condition, failure.message);
  std::fflush(stderr);
  std::abort();
}

}  // namespace

CheckHandler set_check_handler(CheckHandler handler) noexcept {
  return g_check_handler.exchange(handler, std::memory_order_acq_rel);
}

void check_failed(const CheckFailure& failure) {
  if (CheckHandler handler = g_check_handler.load(std::memory_order_acquire)) {
    handler(failure);
  }
  default_check_handler(failure);
}

}  // namespace blockmap
