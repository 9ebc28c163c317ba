#include "millkit/sweep/sweep_config.h"

#include <cmath>
#include <set>

#include "io/toml_section.h"
#include "millkit/io/input_error.h"
#include "sweep/study_input.h"

namespace millkit::sweep {
namespace {

SweepDimension ReadDimension(const TomlSection& section, const driveline::Scene& scene,
                             SweepConfig::Method method) {
  const bool grid = method == SweepConfig::Method::kGrid;
  if (grid) {
    section.RequireOnlyKeys({"name", "lower", "upper", "scale", "points", "values"});
  } else {
    section.RequireOnlyKeys({"name", "lower", "upper", "scale"});
  }
  if (!section.Has("values")) {
    SweepDimension d = ReadParameterRange(section, scene, Scale::kLinear);
    if (grid) d.points = ReadInteger(section, "points", 2, static_cast<int>(kMaxCases));
    return d;
  }
  for (const char* key : {"lower", "upper", "scale", "points"}) {
    if (section.Has(key)) section.Fail(key, "not allowed together with 'values'");
  }
  SweepDimension d;
  d.parameter = ReadParameterName(section, "name", scene);
  d.values = section.NumberArray("values");
  if (d.values.empty()) section.Fail("values", "empty: give at least one value");
  for (double v : d.values) RequireInPhysicalRange(section, "values", d.parameter, v, scene);
  return d;
}

}  // namespace

std::vector<driveline::SceneParameter> SweepConfig::Parameters() const {
  std::vector<driveline::SceneParameter> parameters;
  for (const auto& d : dimensions) parameters.push_back(d.parameter);
  return parameters;
}

CaseList SweepConfig::Cases() const {
  return method == Method::kGrid ? GridCases(dimensions)
                                 : LatinHypercubeCases(dimensions, samples, seed);
}

SweepConfig LoadSweepConfig(const std::string& path, const driveline::Scene& scene) {
  const toml::table root = LoadTomlFile(path);
  const TomlSection top(root, path, "");
  top.RequireOnlyKeys({"sweep", "parameter"});
  SweepConfig config;
  config.file = path;
  const auto sweep = top.OptionalTable("sweep");
  if (!sweep) top.Fail("sweep", "is required ([sweep] with method = \"grid\" or \"lhs\")");
  const std::string method = sweep->RequiredString("method");
  if (method == "grid") {
    config.method = SweepConfig::Method::kGrid;
    sweep->RequireOnlyKeys({"method", "links"});
  } else if (method == "lhs") {
    config.method = SweepConfig::Method::kLatinHypercube;
    sweep->RequireOnlyKeys({"method", "samples", "seed", "links"});
    config.samples = ReadInteger(*sweep, "samples", 1, static_cast<int>(kMaxCases));
    if (sweep->Has("seed")) {
      config.seed = static_cast<std::uint64_t>(ReadInteger(*sweep, "seed", 0, 2147483647));
    }
  } else {
    sweep->Fail("method", "must be \"grid\" or \"lhs\" (got \"" + method + "\")");
  }
  config.links = sweep->Has("links") ? ReadLinkNames(*sweep, "links", scene) : AllLinks(scene);

  const auto sections = top.TableArray("parameter");
  if (sections.empty()) top.Fail("parameter", "at least one [[parameter]] is required");
  std::set<std::string> seen;
  double cases = 1.0;
  for (const auto& section : sections) {
    config.dimensions.push_back(ReadDimension(section, scene, config.method));
    const std::string& name = config.dimensions.back().parameter.name;
    if (!seen.insert(name).second) section.Fail("name", "parameter '" + name + "' swept twice");
    const auto& d = config.dimensions.back();
    cases *= d.values.empty() ? d.points : static_cast<double>(d.values.size());
  }
  if (config.method == SweepConfig::Method::kGrid && cases > static_cast<double>(kMaxCases)) {
    top.Fail("parameter", "the grid has " + FormatNumber(cases) + " cases, more than " +
                              FormatNumber(static_cast<double>(kMaxCases)) +
                              "; use fewer points or method = \"lhs\"");
  }
  return config;
}

}  // namespace millkit::sweep
