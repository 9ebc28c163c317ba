// libFuzzer harness: scene TOML (LoadScene, include/millkit/driveline/scene.h). Seeds:
// datasets/scenes/*.toml.
#include "fuzz/fuzz_input.h"
#include "millkit/driveline/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = millkit::fuzz::WriteInput(data, size, "scene.toml");
  return millkit::fuzz::Outcome([&] { millkit::driveline::LoadScene(path.string()); });
}
