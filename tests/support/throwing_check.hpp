// Test support: turns CHECK failures into exceptions for the duration of a scope, so a test can
// assert that a precondition is enforced without killing the test process.
#pragma once

#include <stdexcept>
#include <string>

#include "blockmap/core/check.hpp"

namespace blockmap::testing {

class CheckFailedError : public std::runtime_error {
 public:
  explicit CheckFailedError(const CheckFailure& failure)
      : std::runtime_error(std::string(failure.message) + " [" + failure.condition + "]") {}
};

class ThrowOnCheckFailure {
 public:
  ThrowOnCheckFailure() noexcept : previous_(set_check_handler(&throw_failure)) {}
  ~ThrowOnCheckFailure() { set_check_handler(previous_); }
  ThrowOnCheckFailure(const ThrowOnCheckFailure&) = delete;
  ThrowOnCheckFailure& operator=(const ThrowOnCheckFailure&) = delete;

 private:
  [[noreturn]] static void throw_failure(const CheckFailure& failure) {
    throw CheckFailedError(failure);
  }
  CheckHandler previous_;
};

}  // namespace blockmap::testing
