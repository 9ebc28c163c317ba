// Bad user input: files, options, values. The message names the file (and row, column or key)
// and the rule that was broken. The command line maps this exception to exit code 2.
#pragma once

#include <stdexcept>
#include <string>

namespace millkit {

class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

// A solver that could not produce an answer (exit code 1 on the command line). Solvers report
// non-convergence in their Summary; the command line turns a failed Summary into this.
class SolverFailure : public std::runtime_error {
 public:
  explicit SolverFailure(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace millkit
