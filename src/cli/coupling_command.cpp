// millkit coupling SCENE.toml --config COUPLING.toml --out result.json [--curve curve.csv]
//                  [--plot curve.svg] [--threads N]
// Coupling stiffness (and damping) optimisation with NLopt (issue 5; docs/coupling.md). The
// configuration keys are documented in include/millkit/optimize/coupling/coupling_config.h.
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "cli/default_threads.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/input_error.h"
#include "millkit/io/output_files.h"
#include "millkit/io/svg_plot.h"
#include "millkit/optimize/coupling/coupling_config.h"
#include "millkit/optimize/coupling/coupling_report.h"

namespace millkit::cli {
namespace {

struct CouplingArgs {
  std::string scene;
  std::string config;
  std::string out;
  std::string curve;
  std::string plot;
  int threads = DefaultThreads();
};

void RunCoupling(const CouplingArgs& args) {
  const driveline::Scene scene = driveline::LoadScene(args.scene);
  coupling::CouplingStudy study = coupling::LoadCouplingStudy(args.config, scene);
  study.curve.threads = args.threads;
  study.curve.Validate();
  CheckOutputPaths({{"--out", args.out}, {"--curve", args.curve}, {"--plot", args.plot}},
                   {args.scene, args.config});

  const coupling::CouplingResult result =
      coupling::OptimizeCoupling(scene, study.problem, study.options);
  std::cerr << "coupling: " << result.summary.BriefReport() << "\n";
  if (!result.summary.found) throw SolverFailure(args.config + ": " + result.summary.message);

  // Everything is computed before the first file is written.
  const std::string json = coupling::CouplingResultJson(scene, study.problem, result);
  std::string csv, svg;
  if (!args.curve.empty() || !args.plot.empty()) {
    const auto curve = coupling::CouplingCurve(scene, study.problem, result.best.values,
                                               study.curve, study.options.simulation);
    csv = coupling::FormatCurveCsv(scene, study.problem, curve);
    PlotOptions options;
    options.title = scene.name + ": Kd around the optimum";
    svg =
        RenderSvgPlot(coupling::CurvePlotPanels(scene, study.problem, curve, result.best), options);
  }
  WriteFileAtomically(args.out, json);
  if (!args.curve.empty()) WriteFileAtomically(args.curve, csv);
  if (!args.plot.empty()) WriteFileAtomically(args.plot, svg);
  std::cout << "scene: " << scene.name << " (" << args.scene << ")\n"
            << coupling::FormatCouplingTable(scene, study.problem, result);
}

}  // namespace

void AddCouplingCommand(CLI::App& app) {
  auto args = std::make_shared<CouplingArgs>();
  auto* command = app.add_subcommand(
      "coupling",
      "Choose coupling stiffness (and damping) to minimise the largest dynamic factor, within "
      "bounds, twist and natural-frequency limits (NLopt DIRECT-L + BOBYQA/COBYLA)");
  command->add_option("scene", args->scene, "Scene TOML file")->required();
  command
      ->add_option("--config", args->config,
                   "Coupling TOML ([objective], [[variable]], [[twist_limit]], "
                   "[frequency_limit], [optimizer], [curve])")
      ->required();
  command->add_option("--out", args->out, "Result JSON (written atomically)")->required();
  command->add_option("--curve", args->curve, "Kd-vs-variable curve around the optimum, CSV");
  command->add_option("--plot", args->plot, "The same curve as SVG");
  command
      ->add_option("--threads", args->threads,
                   "Worker threads for the curve (1 ... 256; default: the cores this process may "
                   "use)")
      ->default_str(std::to_string(DefaultThreads()));
  command->callback([args] { RunCoupling(*args); });
}

}  // namespace millkit::cli
