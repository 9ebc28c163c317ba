// [mpirun -np N] millkit sweep SCENE.toml --config SWEEP.toml --out cases.csv [--plot kd.svg]
//                [--threads N] [--quiet]
// What-if sweep over named scene parameters (issue 5): one CSV row per case, Kd plots. The
// configuration keys are documented in include/millkit/sweep/sweep_config.h.
#include <exception>
#include <iostream>
#include <memory>
#include <optional>

#include "cli/commands.h"
#include "cli/default_threads.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/input_error.h"
#include "millkit/io/output_files.h"
#include "millkit/io/svg_plot.h"
#include "millkit/sweep/mpi_runner.h"
#include "millkit/sweep/sweep_config.h"
#include "millkit/sweep/sweep_runner.h"
#include "millkit/sweep/sweep_table.h"

namespace millkit::cli {
namespace {

struct SweepArgs {
  std::string scene;
  std::string config;
  std::string out;
  std::string plot;
  int threads = DefaultThreads();
  bool quiet = false;
};

void RunSweep(const SweepArgs& args) {
  const sweep::MpiSession mpi;  // every rank parses and validates the same inputs
  sweep::RunnerOptions runner;
  runner.threads = args.threads;
  runner.progress = args.quiet || !mpi.root() ? nullptr : &std::cerr;
  // A rank whose inputs fail (a file its node does not see) must not leave the others waiting in
  // the gather: every rank learns of it before the cases run, and stops.
  std::optional<driveline::Scene> loaded_scene;
  std::optional<sweep::SweepConfig> loaded_config;
  sweep::CaseList cases;
  std::exception_ptr error;
  try {
    runner.Validate();
    loaded_scene = driveline::LoadScene(args.scene);
    loaded_config = sweep::LoadSweepConfig(args.config, *loaded_scene);
    cases = loaded_config->Cases();
    CheckOutputPaths({{"--out", args.out}, {"--plot", args.plot}}, {args.scene, args.config});
  } catch (...) {
    error = std::current_exception();
  }
  sweep::ThrowIfAnyRankFailed(mpi, error, "reading the sweep's inputs");
  const driveline::Scene& scene = *loaded_scene;
  const sweep::SweepConfig& config = *loaded_config;

  sweep::RunnerSummary summary;
  const auto results = sweep::RunCasesDistributed(
      mpi, sweep::SceneCaseFunction(scene, config.Parameters(), sweep::StudySimulationOptions()),
      cases, runner, &summary);
  if (!mpi.root()) return;  // rank 0 reports and writes
  std::cerr << "sweep: " << summary.BriefReport();
  if (mpi.size() > 1) std::cerr << " per rank, " << mpi.size() << " MPI ranks";
  std::cerr << "\n";
  if (summary.failed > 0) {
    std::cerr << "sweep: " << summary.failed
              << " case(s) failed; each is reported in its row (status, message)\n";
  }
  // Everything is computed before the first file is written.
  const std::string csv = sweep::FormatSweepCsv(scene, config, cases, results);
  std::string svg;
  if (!args.plot.empty()) {
    PlotOptions options;
    options.title = scene.name + ": " + std::to_string(cases.size()) + " cases";
    svg = RenderSvgPlot(sweep::SweepPlotPanels(scene, config, cases, results), options);
  }
  WriteFileAtomically(args.out, csv);
  if (!args.plot.empty()) WriteFileAtomically(args.plot, svg);
  if (summary.failed > 0) throw NotTrusted("sweep");  // a batch with failed rows: exit 3
}

}  // namespace

void AddSweepCommand(CLI::App& app) {
  auto args = std::make_shared<SweepArgs>();
  auto* command = app.add_subcommand(
      "sweep",
      "What-if sweep (grid or Latin hypercube) over scene parameters: Kd and peak torque per "
      "link for every case, to CSV, with Kd plots");
  command->add_option("scene", args->scene, "Scene TOML file")->required();
  command->add_option("--config", args->config, "Sweep TOML ([sweep], [[parameter]])")->required();
  command->add_option("--out", args->out, "Cases CSV, one row per case (written atomically)")
      ->required();
  command->add_option("--plot", args->plot, "SVG of Kd against each swept parameter");
  command
      ->add_option("--threads", args->threads,
                   "Worker threads per MPI rank (1 ... 256; default: the cores this process may "
                   "use, shared among the MPI ranks on the node)")
      ->default_str(std::to_string(DefaultThreads()));
  command->add_flag("--quiet", args->quiet, "No progress line on stderr");
  command->callback([args] { RunSweep(*args); });
}

}  // namespace millkit::cli
