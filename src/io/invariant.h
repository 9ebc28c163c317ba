// Always-on invariant checks: a broken precondition of an internal function is a bug in MillKit,
// reported in every build type as std::logic_error naming the condition and the place (assert is
// compiled out in Release builds). Not for user input: that is an InputError naming the file and
// key.
#pragma once

#include <stdexcept>
#include <string>

namespace millkit::internal {

[[noreturn]] inline void FailCheck(const char* condition, const char* what, const char* file,
                                   int line) {
  throw std::logic_error(std::string(file) + ":" + std::to_string(line) + ": invariant '" +
                         condition + "' broken: " + what);
}

}  // namespace millkit::internal

#define MILLKIT_CHECK(condition, what)                                                      \
  do {                                                                                      \
    if (!(condition)) ::millkit::internal::FailCheck(#condition, what, __FILE__, __LINE__); \
  } while (false)
