// Reading the parts that sweep and coupling configurations share: scene parameter names (through
// driveline::ParseSceneParameter, the one parser of names), parameter ranges checked against the
// physical range of their kind, link lists and integers. Each throws InputError naming the file,
// the table, the key and the rule.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "io/toml_section.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/sweep/sample_plan.h"

namespace millkit::sweep {

// The scene parameter named by string key `key`.
driveline::SceneParameter ReadParameterName(const TomlSection& section, const std::string& key,
                                            const driveline::Scene& scene);

// Throws unless `value` lies in the physical range of the parameter's kind (e.g. damping >= 0)
// and, for bite_time, before the end of the run (a load that starts after it leaves no final
// load to scale and no Kd).
void RequireInPhysicalRange(const TomlSection& section, const std::string& key,
                            const driveline::SceneParameter& parameter, double value,
                            const driveline::Scene& scene);

// Keys `name`, `lower`, `upper` (required) and `scale` ("linear" | "log", optional) of a range
// table. lower == upper is an empty range, lower > upper reversed bounds; both must lie in the
// physical range, and a log scale needs lower > 0. `default_scale` applies when `scale` is absent;
// nullopt: log for stiffness, linear for everything else. Other keys are the caller's business.
SweepDimension ReadParameterRange(const TomlSection& section, const driveline::Scene& scene,
                                  std::optional<Scale> default_scale);

// A required integer in [low, high].
int ReadInteger(const TomlSection& section, const std::string& key, int low, int high);

// An array of link names: known to the scene, each once, at least one.
std::vector<int> ReadLinkNames(const TomlSection& section, const std::string& key,
                               const driveline::Scene& scene);
// The index of a link named by string key `key`.
int ReadLinkName(const TomlSection& section, const std::string& key, const driveline::Scene& scene);
std::vector<int> AllLinks(const driveline::Scene& scene);

}  // namespace millkit::sweep
