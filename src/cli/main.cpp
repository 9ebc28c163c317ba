// millkit: one program, subcommands with --help (SPEC §8).
// Exit codes: 0 success, 2 bad input, 1 solver failure, 3 outputs written but the result not
// trusted (an identification whose verdict is not ok).
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "cli/commands.h"
#include "millkit/io/input_error.h"
#include "millkit/version.h"

int main(int argc, char** argv) {
  CLI::App app{"MillKit: rolling-mill drive-line dynamics, identification and leveller setpoints"};
  app.set_version_flag("--version", std::string("millkit ") + MILLKIT_VERSION_STRING);
  app.require_subcommand(1);
  millkit::cli::AddSimulateCommand(app);
  millkit::cli::AddLevellerCommand(app);
  millkit::cli::AddBalancerCommand(app);
  millkit::cli::AddIdentifyCommand(app);
  millkit::cli::AddCouplingCommand(app);
  millkit::cli::AddSweepCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  } catch (const millkit::InputError& e) {
    std::cerr << "millkit: error: " << e.what() << "\n";
    return 2;
  } catch (const millkit::NotTrusted&) {
    return 3;
  } catch (const millkit::SolverFailure& e) {
    std::cerr << "millkit: solver failure: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "millkit: internal error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
