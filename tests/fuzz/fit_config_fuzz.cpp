// libFuzzer harness: fit config TOML (LoadFitConfig, include/millkit/identify/fit_config.h),
// checked against the bundled scene and record it was written for. Seeds:
// datasets/records/*.fit.toml.
#include "fuzz/fuzz_input.h"
#include "millkit/driveline/scene.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const millkit::driveline::Scene scene =
      millkit::driveline::LoadScene(millkit::fuzz::DatasetPath("scenes/mill5_bite.toml"));
  static const millkit::identify::Oscillogram record = millkit::identify::LoadOscillogram(
      millkit::fuzz::DatasetPath("records/mill5_balanced_lower.csv"));
  const auto path = millkit::fuzz::WriteInput(data, size, "fit.toml");
  return millkit::fuzz::Outcome(
      [&] { millkit::identify::LoadFitConfig(path.string(), record, scene); });
}
