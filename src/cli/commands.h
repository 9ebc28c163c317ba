// Subcommands of the `millkit` program. Each Add*Command registers one subcommand on `app`; its
// callback parses, calls the library and writes files. Bad input throws InputError (exit 2),
// a failed solve throws SolverFailure (exit 1). No physics here.
#pragma once

#include <CLI/CLI.hpp>

namespace millkit::cli {

void AddSimulateCommand(CLI::App& app);
void AddLevellerCommand(CLI::App& app);
void AddBalancerCommand(CLI::App& app);
void AddIdentifyCommand(CLI::App& app);
void AddSynthesizeCommand(CLI::App& app);
void AddCouplingCommand(CLI::App& app);
void AddSweepCommand(CLI::App& app);

}  // namespace millkit::cli
