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

// The work finished and its outputs are written, but its result is not trusted (exit code 3):
// e.g. an identification whose verdict is not ok. The reasons are already on stderr and in the
// outputs; the message names the command.
class NotTrusted : public std::runtime_error {
 public:
  explicit NotTrusted(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace millkit
