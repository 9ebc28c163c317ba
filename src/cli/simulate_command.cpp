// millkit simulate SCENE.toml --out result.csv [--solver exact|cvode] [--rtol X] [--atol X]
//                  [--no-check] [--every N] [--columns LIST] [--kd-only] [--quiet]
#include <iostream>
#include <memory>
#include <optional>

#include "cli/commands.h"
#include "millkit/driveline/result_csv.h"
#include "millkit/driveline/simulation.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"
#include "millkit/io/output_files.h"
#include "millkit/io/progress_line.h"

namespace millkit::cli {
namespace {

struct SimulateArgs {
  std::string scene;
  std::string out;
  std::string solver = "exact";
  double rtol = 1e-8;
  std::optional<double> atol;
  bool no_check = false;
  int every = 1;
  std::string columns;
  bool kd_only = false;
  bool quiet = false;
};

void RunSimulate(const SimulateArgs& args) {
  if (args.kd_only) {
    if (!args.out.empty()) throw InputError("option --out: --kd-only writes no CSV; drop --out");
  } else if (args.out.empty()) {
    throw InputError("option --out: required (or --kd-only for the Kd table alone)");
  }
  if (args.every < 1) {
    throw InputError("option --every: must be >= 1 (got " + std::to_string(args.every) + ")");
  }
  CheckOutputPaths({{"--out", args.out}}, {args.scene});
  driveline::SimulationOptions options;
  const driveline::SolverInfo* solver = driveline::FindSolver(args.solver);
  if (solver == nullptr) {
    throw InputError("option --solver: must be one of " + driveline::SolverNames() + " (got '" +
                     args.solver + "')");
  }
  options.solver = solver->kind;
  options.rtol = args.rtol;
  options.atol = args.atol;
  options.Validate();
  const driveline::Model model(driveline::LoadScene(args.scene));
  const driveline::Scene& scene = model.scene();
  for (const auto& line : model.reduction().report) std::cerr << "band reduction: " << line << "\n";

  // Rows go to the file as the run produces them; only the peaks are held (keep_samples = false).
  options.keep_samples = false;
  std::optional<AtomicFile> file;
  std::optional<driveline::ResultCsvWriter> writer;
  if (!args.kd_only) {
    auto columns = args.columns.empty()
                       ? driveline::AllResultColumns(scene)
                       : driveline::SelectResultColumns(scene, args.columns, "--columns");
    const double bytes = driveline::EstimatedCsvBytes(
        driveline::KeptRows(scene.SampleCount(), args.every), static_cast<int>(columns.size()) + 1);
    const std::string warning = driveline::LargeOutputWarning(args.out, bytes);
    if (!warning.empty()) std::cerr << warning << "\n";
    file.emplace(args.out);
    writer.emplace(&file->stream(), args.out, std::move(columns), args.every);
    options.sample_sink = [&writer](const driveline::OutputSample& sample) {
      writer->Write(sample);
    };
  }
  const bool check = options.solver == driveline::SolverKind::kCvode && !args.no_check;
  ProgressLine progress(args.quiet ? nullptr : &std::cerr, "simulate");
  const std::string of_run = check && options.rtol / 10.0 >= driveline::kMinRtol
                                 ? " of both runs (rtol and rtol/10)"
                                 : " of " + FormatNumber(scene.duration_s) + " s";
  options.progress = [&](double fraction) {
    if (!progress.Due()) return;
    progress.Update(std::to_string(static_cast<int>(100.0 * fraction)) + " %" + of_run);
  };
  const auto result =
      check ? driveline::SimulateCvodeChecked(model, options) : driveline::Simulate(model, options);
  progress.Finish();
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
  if (file) file->Commit();
  std::cout << "scene: " << scene.name << " (" << args.scene << ")\n"
            << driveline::FormatDynamicFactorTable(driveline::DynamicFactors(model, result));
}

}  // namespace

void AddSimulateCommand(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  auto* command = app.add_subcommand(
      "simulate",
      "Simulate a drive-line scene; write link torques, speeds and twists to CSV and print the "
      "dynamic-factor table. Reference: docs/simulate.md");
  command->add_option("scene", args->scene, "Scene TOML file")->required();
  command->add_option("--out", args->out,
                      "Result CSV, written row by row as the run goes (atomically: nothing is "
                      "left on failure). Required unless --kd-only");
  std::string solvers;
  for (const driveline::SolverInfo& info : driveline::Solvers()) {
    solvers += solvers.empty() ? "" : "; ";
    solvers += info.name;
    solvers += ": ";
    solvers += info.description;
  }
  command->add_option("--solver", args->solver, "Solver (default exact). " + solvers);
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
  auto* every = command->add_option(
      "--every", args->every,
      "Write every N-th output sample (k = 0, N, 2N, ...; default 1). Kd is still taken over "
      "every sample");
  auto* columns = command->add_option(
      "--columns", args->columns,
      "Comma list of the columns to write after time, in that order: link names (torque), "
      "speed.<mass>, twist.<link> (default: all)");
  command
      ->add_flag("--kd-only", args->kd_only,
                 "Print the dynamic-factor table only: no CSV, no samples held (the fastest run)")
      ->excludes(every)
      ->excludes(columns);
  command->add_flag("--quiet", args->quiet, "No progress line on stderr");
  command->callback([args] { RunSimulate(*args); });
}

}  // namespace millkit::cli
