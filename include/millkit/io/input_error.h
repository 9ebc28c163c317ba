// Bad user input: files, options, values. The message names the file (and row, column or key)
// and the rule that was broken. The command line maps this exception to exit code 2.
#pragma once

#include <stdexcept>
#include <string>

namespace millkit {

class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}

  // A rule broken by a field of an options struct: the message is "<Struct>::<field>: <rule>"
  // (e.g. "SimulationOptions::rtol: must lie in [1e-14, 1e-2]"). The library names its own
  // fields; a command line that sets the field from a flag names the flag instead (option()).
  static InputError Option(const std::string& options_struct, const std::string& field,
                           const std::string& rule) {
    InputError error(options_struct + "::" + field + ": " + rule);
    error.option_ = options_struct + "::" + field;
    error.rule_ = rule;
    return error;
  }
  // "<Struct>::<field>" for an option error (else empty), and the rule alone.
  const std::string& option() const { return option_; }
  const std::string& rule() const { return rule_; }

 private:
  std::string option_;
  std::string rule_;
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
