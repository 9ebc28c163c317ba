// The coupling-optimisation configuration (`millkit coupling SCENE.toml --config C.toml`):
//
//   [objective]
//   links = ["upper_spindle", "lower_spindle"]  # Kd counted (default: every link); each must
//                                               # carry a static torque (Kd defined)
//   [[variable]]                    # one per optimised quantity, at least one
//   name = "upper_spindle.stiffness"   # <link>.stiffness or <link>.damping (scene_parameter.h)
//   lower = 2.0e6                   # bounds: lower < upper, inside the physical range
//   upper = 6.0e7
//   scale = "log"                   # optional; default log for stiffness, linear for damping
//
//   [[twist_limit]]                 # optional, at most one per link
//   link = "upper_spindle"
//   max_twist = 0.03                # rad: b/2 + |T_rated|/c <= max_twist
//   rated_torque = 150000.0         # N*m, optional: default |m_s| of the link under the
//                                   # scene's final loads (SPEC §2.5)
//   [frequency_limit]               # optional
//   min_frequency = 8.0             # Hz: lowest natural frequency, gaps closed, >= this
//
//   [optimizer]                     # optional
//   global_evaluations = 200        # DIRECT-L budget, >= 1 (NLopt may overshoot by a few)
//   local = "bobyqa"                # bobyqa | cobyla | none
//   local_evaluations = 100         # polish budget, >= 1 unless local = "none"
//   xtol = 1e-5                     # stopping step on the unit cube, in (0, 1)
//
//   [curve]                         # optional: the Kd-vs-variable curve around the answer
//   points = 41                     # per variable, in [2, 10000]
//   width = 0.5                     # fraction of the (log) range on each side, in (0, 1]
//
// Every broken rule is an InputError naming the file, the table, the key and the rule.
#pragma once

#include <string>

#include "millkit/driveline/scene.h"
#include "millkit/optimize/coupling/coupling_optimizer.h"

namespace millkit::coupling {

struct CouplingStudy {
  CouplingProblem problem;
  CouplingOptions options;
  CurveOptions curve;
};

CouplingStudy LoadCouplingStudy(const std::string& path, const driveline::Scene& scene);

}  // namespace millkit::coupling
