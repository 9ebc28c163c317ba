// Placeholder until the drive line lands.
#include "cli/commands.h"
#include "io/input_error.h"

namespace millkit::cli {
void AddSimulateCommand(CLI::App& app) {
  auto* command = app.add_subcommand("simulate", "Simulate a drive-line scene (not built yet)");
  command->callback([] { throw SolverFailure("simulate is not built yet"); });
}
}  // namespace millkit::cli
