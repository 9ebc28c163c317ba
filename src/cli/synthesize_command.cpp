// millkit synthesize SCENE.toml --spec record.toml --out record.csv [--quiet]
#include <iostream>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "millkit/driveline/scene.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/identify/record_generator.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/number_format.h"
#include "millkit/io/output_files.h"
#include "millkit/io/progress_line.h"

namespace millkit::cli {
namespace {

struct SynthesizeArgs {
  std::string scene;
  std::string spec;
  std::string out;
  bool quiet = false;
};

void RunSynthesize(const SynthesizeArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.scene, args.spec});
  AtomicFile file(args.out);
  driveline::Scene scene = driveline::LoadScene(args.scene);
  const auto spec = identify::LoadRecordSpec(args.spec, &scene);
  ProgressLine progress(args.quiet ? nullptr : &std::cerr, "synthesize");
  const double duration_s =
      spec.defects.duration_s > 0.0 ? spec.defects.duration_s : scene.duration_s;
  const auto record = identify::GenerateRecord(scene, spec, [&](double fraction) {
    if (!progress.Due()) return;
    progress.Update(std::to_string(static_cast<int>(100.0 * fraction)) + " % of " +
                    FormatNumber(duration_s) + " s simulated");
  });
  progress.Finish();
  file.stream() << identify::FormatOscillogram(record);
  file.Commit();
}

}  // namespace

void AddSynthesizeCommand(CLI::App& app) {
  auto synth = std::make_shared<SynthesizeArgs>();
  auto* generator = app.add_subcommand(
      "synthesize",
      "Make a synthetic oscillogram from a scene and a record spec (true parameters, noise, "
      "gain, offset, quantisation, anti-alias filter)");
  generator->add_option("scene", synth->scene, "Scene TOML file")->required();
  generator->add_option("--spec", synth->spec, "Record spec TOML ([record], [truth], [[channel]])")
      ->required();
  generator->add_option("--out", synth->out, "Record CSV (written atomically)")->required();
  generator->add_flag("--quiet", synth->quiet, "No progress line on stderr");
  generator->callback([synth] { RunSynthesize(*synth); });
}

}  // namespace millkit::cli
