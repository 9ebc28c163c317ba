// libFuzzer harness: sweep config TOML (LoadSweepConfig, include/millkit/sweep/sweep_config.h)
// on the bundled scene. Seeds: datasets/studies/mill5_lhs.toml, mill5_wear_grid.toml.
#include "fuzz/fuzz_input.h"
#include "millkit/driveline/scene.h"
#include "millkit/sweep/sweep_config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const millkit::driveline::Scene scene =
      millkit::driveline::LoadScene(millkit::fuzz::DatasetPath("scenes/mill5_bite.toml"));
  const auto path = millkit::fuzz::WriteInput(data, size, "sweep.toml");
  return millkit::fuzz::Outcome([&] { millkit::sweep::LoadSweepConfig(path.string(), scene); });
}
