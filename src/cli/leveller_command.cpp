// Placeholder until the leveller lands; replaced by the real subcommand.
#include "cli/commands.h"
#include "io/input_error.h"

namespace millkit::cli {

void AddLevellerCommand(CLI::App& app) {
  auto* command = app.add_subcommand("leveller", "Leveller (not built yet)");
  command->callback([] { throw SolverFailure("the leveller is not built yet"); });
}

}  // namespace millkit::cli
