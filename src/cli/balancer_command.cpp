// Placeholder until the balancer lands; replaced by the real subcommand.
#include "cli/commands.h"
#include "io/input_error.h"

namespace millkit::cli {

void AddBalancerCommand(CLI::App& app) {
  auto* command = app.add_subcommand("balancer", "Balancer (not built yet)");
  command->callback([] { throw SolverFailure("the balancer is not built yet"); });
}

}  // namespace millkit::cli
