// The what-if sweep configuration (`millkit sweep SCENE.toml --config SWEEP.toml`, issue 5):
//
//   [sweep]
//   method = "grid"            # grid | lhs (Latin hypercube)
//   samples = 200              # lhs only: number of cases, 1 … 1e6
//   seed = 1                   # lhs only: generator seed, integer >= 0 (default 1)
//   links = ["upper_spindle"]  # optional: links reported in the table and plots (default: all)
//
//   [[parameter]]              # one per swept parameter, at least one
//   name = "upper_spindle.damping"   # a scene parameter (millkit/driveline/scene_parameter.h)
//   lower = 1000.0             # range: lower < upper, both inside the parameter's physical range
//   upper = 20000.0
//   scale = "linear"           # linear | log (log needs lower > 0); default linear
//   points = 5                 # grid only: values over [lower, upper], ends included, >= 2
//   # values = [0.0, 0.01]     # grid only, instead of lower/upper/scale/points: explicit values
//
// Every rule broken is an InputError naming the file, the table, the key and the rule: unknown
// keys, unknown parameter names or links, a parameter named twice, empty or reversed ranges,
// values outside the physical range, keys of the other method, more than kMaxCases cases.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/sweep/sample_plan.h"

namespace millkit::sweep {

inline constexpr long kMaxCases = 1'000'000;

struct SweepConfig {
  enum class Method { kGrid, kLatinHypercube };
  std::string file;
  Method method = Method::kGrid;
  int samples = 0;         // lhs
  std::uint64_t seed = 1;  // lhs
  std::vector<SweepDimension> dimensions;
  std::vector<int> links;  // scene link indices reported

  CaseList Cases() const;
  std::vector<driveline::SceneParameter> Parameters() const;
};

SweepConfig LoadSweepConfig(const std::string& path, const driveline::Scene& scene);

}  // namespace millkit::sweep
