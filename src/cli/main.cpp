// millkit: one program, subcommands with --help (SPEC §8).
// Exit codes: 0 success, 2 bad input, 1 solver failure, 3 outputs written but the result not
// trusted (an identification whose verdict is not ok).
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <string>
#include <utility>

#include "cli/commands.h"
#include "millkit/io/input_error.h"
#include "millkit/io/output_files.h"
#include "millkit/version.h"

namespace {

// Library messages name the options struct field a command line sets from a flag; the user of
// the command line reads the flag.
std::string InCommandLineTerms(std::string message) {
  static const std::pair<const char*, const char*> kFlags[] = {
      {"SimulationOptions::rtol", "option --rtol"},
      {"SimulationOptions::atol", "option --atol"},
      {"RunnerOptions::threads", "option --threads"},
      {"CampaignOptions::threads", "option --threads"},
      {"TableOptions::encoder_deg", "option --encoder-deg"},
      {"ForcesOptions::shape_factor", "option --shape-factor"},
      {"ForcesOptions::mw_override_Nm", "option --mw-nm"},
      {"ForcesOptions::original_curvature_per_m", "option --original-curvature-per-m"},
      {"RecordOptions::time_column", "--time-column"}};
  for (const auto& [field, flag] : kFlags) {
    const std::string key = field;
    for (auto at = message.find(key); at != std::string::npos; at = message.find(key, at)) {
      message.replace(at, key.size(), flag);
      at += std::char_traits<char>::length(flag);
    }
  }
  return message;
}

}  // namespace

int main(int argc, char** argv) {
  // Ctrl-C, SIGTERM or SIGHUP in the middle of a run leave no temporary output behind.
  millkit::InstallTemporaryFileCleanup();
  CLI::App app{"MillKit: rolling-mill drive-line dynamics, identification and leveller setpoints"};
  app.set_version_flag("--version", std::string("millkit ") + MILLKIT_VERSION_STRING);
  app.require_subcommand(1);
  millkit::cli::AddSimulateCommand(app);
  millkit::cli::AddLevellerCommand(app);
  millkit::cli::AddBalancerCommand(app);
  millkit::cli::AddIdentifyCommand(app);
  millkit::cli::AddSynthesizeCommand(app);
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
    std::cerr << "millkit: error: " << InCommandLineTerms(e.what()) << "\n";
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
