// libFuzzer harness: coupling study TOML (LoadCouplingStudy,
// include/millkit/optimize/coupling/coupling_config.h) on the bundled scene. Seed:
// datasets/studies/mill5_coupling.toml.
#include "fuzz/fuzz_input.h"
#include "millkit/driveline/scene.h"
#include "millkit/optimize/coupling/coupling_config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const millkit::driveline::Scene scene =
      millkit::driveline::LoadScene(millkit::fuzz::DatasetPath("scenes/mill5_bite.toml"));
  const auto path = millkit::fuzz::WriteInput(data, size, "coupling.toml");
  return millkit::fuzz::Outcome(
      [&] { millkit::coupling::LoadCouplingStudy(path.string(), scene); });
}
