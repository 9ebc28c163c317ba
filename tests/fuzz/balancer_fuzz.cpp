// libFuzzer harness: balancer device TOML as `millkit balancer --config` reads it
// (ReadBalancerInputFile, include/millkit/balancer/balancer_input.h). Seed:
// datasets/balancer/seed_002_stand950.toml.
#include "fuzz/fuzz_input.h"
#include "millkit/balancer/balancer_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = millkit::fuzz::WriteInput(data, size, "balancer.toml");
  return millkit::fuzz::Outcome([&] { millkit::balancer::ReadBalancerInputFile(path); });
}
