// libFuzzer harness: leveller geometry TOML (LoadLevellerConfig,
// include/millkit/leveller/leveller_config.h), including its linkage check. Seed:
// datasets/leveller/leveller_default.toml.
#include "fuzz/fuzz_input.h"
#include "millkit/leveller/leveller_config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = millkit::fuzz::WriteInput(data, size, "leveller.toml");
  return millkit::fuzz::Outcome([&] { millkit::leveller::LoadLevellerConfig(path); });
}
