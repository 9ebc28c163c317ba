// millkit simulate SCENE.toml --out result.csv [--solver exact|cvode] [--rtol X] [--atol X]
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "driveline/simulation.h"
#include "io/atomic_file.h"
#include "io/input_error.h"
#include "io/output_files.h"
#include "io/toml_section.h"

namespace millkit::cli {
namespace {

struct SimulateArgs {
  std::string scene;
  std::string out;
  std::string solver = "exact";
  double rtol = 1e-8;
  std::optional<double> atol;
  bool no_check = false;
};

void WriteResultCsv(const driveline::Scene& scene, const driveline::SimulationResult& result,
                    const std::string& path) {
  AtomicFile file(path);
  std::ostream& out = file.stream();
  out << "time";
  for (const auto& link : scene.links) out << "," << link.name;
  for (const auto& mass : scene.masses) out << ",speed." << mass.name;
  for (const auto& link : scene.links) out << ",twist." << link.name;
  out << "\n";
  // Shortest round-trip text for every number (std::to_chars): exact and fast.
  std::string line;
  const auto append = [&line](double value) { AppendNumber(value, &line); };
  for (size_t k = 0; k < result.time_s.size(); ++k) {
    const int row = static_cast<int>(k);
    line.clear();
    append(result.time_s[k]);
    for (const auto* block :
         {&result.link_torque_Nm, &result.mass_speed_rad_per_s, &result.link_twist_rad}) {
      for (int j = 0; j < block->cols(); ++j) {
        line += ',';
        append((*block)(row, j));
      }
    }
    line += '\n';
    out << line;
  }
  file.Commit();
}

void RunSimulate(const SimulateArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.scene});
  driveline::SimulationOptions options;
  if (args.solver == "exact") {
    options.solver = driveline::SolverKind::kExact;
  } else if (args.solver == "cvode") {
    options.solver = driveline::SolverKind::kCvode;
  } else {
    throw InputError("option --solver: must be exact or cvode (got '" + args.solver + "')");
  }
  options.rtol = args.rtol;
  options.atol = args.atol;
  options.Validate();
  const driveline::Model model(driveline::LoadScene(args.scene));
  for (const auto& line : model.reduction().report) std::cerr << "band reduction: " << line << "\n";
  const bool check = options.solver == driveline::SolverKind::kCvode && !args.no_check;
  const auto result =
      check ? driveline::SimulateCvodeChecked(model, options) : driveline::Simulate(model, options);
  std::cerr << result.summary.BriefReport() << "\n";
  if (!result.summary.success) throw SolverFailure(args.scene + ": " + result.summary.message);
  const double target = options.solver == driveline::SolverKind::kExact
                            ? driveline::kExactErrorTarget
                            : driveline::kCvodeErrorTarget;
  if ((options.solver == driveline::SolverKind::kExact || check) &&
      !(result.summary.error_estimate <= target)) {
    std::cerr << "warning: " << result.summary.error_kind << " " << result.summary.error_estimate
              << " is above " << target
              << (options.solver == driveline::SolverKind::kExact
                      ? "; the result is written, but its accuracy is only that"
                      : "; tighten --rtol, or use --solver exact")
              << "\n";
  }
  WriteResultCsv(model.scene(), result, args.out);
  std::cout << "scene: " << model.scene().name << " (" << args.scene << ")\n"
            << driveline::FormatDynamicFactorTable(driveline::DynamicFactors(model, result));
}

}  // namespace

void AddSimulateCommand(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  auto* command = app.add_subcommand(
      "simulate",
      "Simulate a drive-line scene; write link torques, speeds and twists to CSV and print the "
      "dynamic-factor table");
  command->add_option("scene", args->scene, "Scene TOML file")->required();
  command->add_option("--out", args->out, "Result CSV (written atomically)")->required();
  command->add_option("--solver", args->solver, "exact (default) or cvode");
  command->add_option("--rtol", args->rtol,
                      "CVODE relative tolerance (default 1e-8). CVODE runs twice, the second time "
                      "at rtol/10, and reports the difference as its error (warning above 1e-6 "
                      "of peak torque)");
  command->add_flag("--no-check", args->no_check,
                    "CVODE: one run only, reporting the requested tolerance instead of a "
                    "measured error");
  command->add_option("--atol", args->atol,
                      "CVODE absolute tolerance as a fraction of each state's typical size "
                      "(default: rtol)");
  command->callback([args] { RunSimulate(*args); });
}

}  // namespace millkit::cli
