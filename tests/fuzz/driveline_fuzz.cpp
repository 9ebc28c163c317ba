// libFuzzer harness (issue 11): the input's first 8 bytes seed the extreme-scene generator
// (tests/driveline/extreme_scenes.h); the rest, when present, scale the scene's stiffness,
// damping, gap and rise by powers of ten. Both solvers run; the harness traps on anything but an
// answer or a clear failure: an exception other than InputError, a failure without a reason, or
// non-finite samples in a run that reports success. libFuzzer's -timeout catches hangs.
// Build: cmake -DCMAKE_CXX_COMPILER=clang++-14 -DMILLKIT_BUILD_FUZZERS=ON; run:
//   build/tests/fuzz/driveline_fuzz -max_total_time=60 -timeout=10
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>

#include "driveline/extreme_scenes.h"
#include "millkit/driveline/simulation.h"
#include "millkit/io/input_error.h"

using namespace millkit::driveline;

namespace {

void Check(const SimulationResult& result) {
  if (!result.summary.success) {
    if (result.summary.message.empty()) __builtin_trap();
    return;
  }
  if (!result.link_torque_Nm.allFinite() || !result.mass_speed_rad_per_s.allFinite()) {
    __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::uint64_t seed = 0;
  std::memcpy(&seed, data, std::min<std::size_t>(size, sizeof(seed)));
  Scene scene = testing::ExtremeSceneGenerator(seed).Next();
  for (std::size_t i = sizeof(seed); i < size; ++i) {
    const double factor = std::pow(10.0, static_cast<int>(data[i] % 7) - 3);
    switch (data[i] / 64) {
      case 0:
        for (auto& link : scene.links) link.stiffness_Nm_per_rad *= factor;
        break;
      case 1:
        for (auto& link : scene.links) link.damping_Nms_per_rad *= factor;
        break;
      case 2:
        for (auto& link : scene.links) link.backlash_rad *= factor;
        break;
      default:
        for (auto& source : scene.torques) {
          source.times_s[1] = source.times_s[0] + (source.times_s[1] - source.times_s[0]) * factor;
        }
    }
  }
  std::optional<Model> model;
  try {
    model.emplace(scene);
  } catch (const millkit::InputError&) {
    return 0;  // refused with a named rule
  }
  Check(Simulate(*model, {}));
  SimulationOptions cvode;
  cvode.solver = SolverKind::kCvode;
  cvode.max_steps = 200000;
  // CVODE chatters where a surface stays at a flank (a million events and 9 s on the input of
  // byte 0x2c alone, which the exact solver answers in 10 ms): a clear failure, sooner.
  cvode.max_events = 10000;
  Check(Simulate(*model, cvode));
  return 0;
}
