#include "sweep/study_input.h"

#include <cmath>
#include <numeric>
#include <set>

#include "millkit/io/input_error.h"

namespace millkit::sweep {

driveline::SceneParameter ReadParameterName(const TomlSection& section, const std::string& key,
                                            const driveline::Scene& scene) {
  return driveline::ParseSceneParameter(scene, section.RequiredString(key),
                                        section.KeyContext(key));
}

void RequireInPhysicalRange(const TomlSection& section, const std::string& key,
                            const driveline::SceneParameter& parameter, double value,
                            const driveline::Scene& scene) {
  if (parameter.kind == driveline::SceneParameter::Kind::kBiteTime &&
      !(value >= 0.0 && value < scene.duration_s)) {
    section.Fail(key, "bite_time must lie in [0, duration = " + FormatNumber(scene.duration_s) +
                          ") so that the load starts within the run (got " + FormatNumber(value) +
                          ")");
  }
  const driveline::ParameterRange range = driveline::PhysicalRange(parameter.kind);
  const bool above = range.lower_inclusive ? value >= range.lower : value > range.lower;
  if (above && value <= range.upper) return;
  std::string rule = parameter.name + " must be ";
  if (std::isinf(range.upper)) {
    rule += (range.lower_inclusive ? ">= " : "> ") + FormatNumber(range.lower);
  } else {
    rule += "in " + std::string(range.lower_inclusive ? "[" : "(") + FormatNumber(range.lower) +
            ", " + FormatNumber(range.upper) + "]";
  }
  section.Fail(key, rule + " (got " + FormatNumber(value) + ")");
}

SweepDimension ReadParameterRange(const TomlSection& section, const driveline::Scene& scene,
                                  std::optional<Scale> default_scale) {
  SweepDimension d;
  d.parameter = ReadParameterName(section, "name", scene);
  d.scale = default_scale.value_or(d.parameter.kind == driveline::SceneParameter::Kind::kStiffness
                                       ? Scale::kLog
                                       : Scale::kLinear);
  if (const auto scale = section.OptionalString("scale")) {
    if (*scale == "log") {
      d.scale = Scale::kLog;
    } else if (*scale == "linear") {
      d.scale = Scale::kLinear;
    } else {
      section.Fail("scale", "must be \"linear\" or \"log\" (got \"" + *scale + "\")");
    }
  }
  d.lower = section.RequiredNumber("lower");
  d.upper = section.RequiredNumber("upper");
  RequireInPhysicalRange(section, "lower", d.parameter, d.lower, scene);
  RequireInPhysicalRange(section, "upper", d.parameter, d.upper, scene);
  if (d.lower == d.upper) {
    section.Fail("upper", "empty range: lower = upper = " + FormatNumber(d.lower) +
                              " (set a fixed value in the scene instead)");
  }
  if (d.lower > d.upper) {
    section.Fail("upper", "bounds reversed: lower " + FormatNumber(d.lower) + " > upper " +
                              FormatNumber(d.upper));
  }
  if (d.scale == Scale::kLog && !(d.lower > 0.0)) {
    section.Fail("lower", "a log scale needs lower > 0 (got " + FormatNumber(d.lower) + ")");
  }
  return d;
}

int ReadInteger(const TomlSection& section, const std::string& key, int low, int high) {
  const double value = section.RequiredNumber(key);
  if (value != std::floor(value) || value < low || value > high) {
    section.Fail(key, "must be an integer in [" + std::to_string(low) + ", " +
                          std::to_string(high) + "] (got " + FormatNumber(value) + ")");
  }
  return static_cast<int>(value);
}

int ReadLinkName(const TomlSection& section, const std::string& key,
                 const driveline::Scene& scene) {
  const std::string name = section.RequiredString(key);
  const int index = scene.LinkIndex(name);
  if (index < 0) section.Fail(key, "no link named '" + name + "' in " + scene.file);
  return index;
}

std::vector<int> ReadLinkNames(const TomlSection& section, const std::string& key,
                               const driveline::Scene& scene) {
  std::vector<int> links;
  std::set<int> seen;
  for (const auto& name : section.RequiredStringArray(key)) {
    const int index = scene.LinkIndex(name);
    if (index < 0) section.Fail(key, "no link named '" + name + "' in " + scene.file);
    if (!seen.insert(index).second) section.Fail(key, "link '" + name + "' listed twice");
    links.push_back(index);
  }
  if (links.empty()) section.Fail(key, "empty: name at least one link");
  return links;
}

std::vector<int> AllLinks(const driveline::Scene& scene) {
  std::vector<int> links(scene.links.size());
  std::iota(links.begin(), links.end(), 0);
  return links;
}

}  // namespace millkit::sweep
