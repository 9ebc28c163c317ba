#include "millkit/optimize/coupling/coupling_config.h"

#include <cmath>
#include <set>

#include "io/toml_section.h"
#include "millkit/driveline/model.h"
#include "millkit/io/input_error.h"
#include "sweep/study_input.h"

namespace millkit::coupling {
namespace {

using driveline::SceneParameter;

void ReadVariables(const TomlSection& top, const driveline::Scene& scene,
                   CouplingProblem* problem) {
  const auto sections = top.TableArray("variable");
  if (sections.empty()) top.Fail("variable", "at least one [[variable]] is required");
  std::set<std::string> seen;
  for (const auto& section : sections) {
    section.RequireOnlyKeys({"name", "lower", "upper", "scale"});
    sweep::SweepDimension d = sweep::ReadParameterRange(section, scene, std::nullopt);
    if (d.parameter.kind != SceneParameter::Kind::kStiffness &&
        d.parameter.kind != SceneParameter::Kind::kDamping) {
      section.Fail("name", "'" + d.parameter.name +
                               "': only <link>.stiffness and <link>.damping can be optimised");
    }
    if (!seen.insert(d.parameter.name).second) {
      section.Fail("name", "variable '" + d.parameter.name + "' given twice");
    }
    problem->variables.push_back(std::move(d));
  }
}

void ReadTwistLimits(const TomlSection& top, const driveline::Scene& scene,
                     CouplingProblem* problem) {
  const std::vector<double> static_torque = driveline::StaticLinkTorques(scene);
  std::set<int> seen;
  for (const auto& section : top.TableArray("twist_limit")) {
    section.RequireOnlyKeys({"link", "max_twist", "rated_torque"});
    TwistLimit limit;
    limit.link = sweep::ReadLinkName(section, "link", scene);
    if (!seen.insert(limit.link).second) section.Fail("link", "a second limit on the same link");
    limit.max_twist_rad = section.Positive("max_twist", section.RequiredNumber("max_twist"));
    if (const auto rated = section.OptionalNumber("rated_torque")) {
      limit.rated_torque_Nm = section.Positive("rated_torque", std::abs(*rated));
    } else {
      limit.rated_torque_Nm = std::abs(static_torque[limit.link]);
      if (limit.rated_torque_Nm == 0.0) {
        section.Fail("link",
                     "the link carries no static torque under the final loads; give "
                     "rated_torque");
      }
    }
    problem->twist_limits.push_back(limit);
  }
}

void ReadOptimizer(const TomlSection& top, CouplingOptions* options) {
  const auto section = top.OptionalTable("optimizer");
  if (!section) return;
  section->RequireOnlyKeys({"global_evaluations", "local", "local_evaluations", "xtol"});
  if (section->Has("global_evaluations")) {
    options->global_evaluations = sweep::ReadInteger(*section, "global_evaluations", 1, 1000000);
  }
  const std::string local = section->String("local", "bobyqa");
  if (local == "bobyqa") {
    options->local_algorithm = optimize::Algorithm::kLnBobyqa;
  } else if (local == "cobyla") {
    options->local_algorithm = optimize::Algorithm::kLnCobyla;
  } else if (local == "none") {
    options->local_evaluations = 0;
    if (section->Has("local_evaluations")) {
      section->Fail("local_evaluations", "not allowed with local = \"none\"");
    }
  } else {
    section->Fail("local", "must be \"bobyqa\", \"cobyla\" or \"none\" (got \"" + local + "\")");
  }
  if (local != "none" && section->Has("local_evaluations")) {
    options->local_evaluations = sweep::ReadInteger(*section, "local_evaluations", 1, 1000000);
  }
  if (section->Has("xtol")) {
    options->xtol = section->RequiredNumber("xtol");
    if (!(options->xtol > 0.0 && options->xtol < 1.0)) {
      section->Fail("xtol", "must lie in (0, 1) (got " + FormatNumber(options->xtol) + ")");
    }
  }
}

void ReadCurve(const TomlSection& top, CurveOptions* curve) {
  const auto section = top.OptionalTable("curve");
  if (!section) return;
  section->RequireOnlyKeys({"points", "width"});
  if (section->Has("points")) curve->points = sweep::ReadInteger(*section, "points", 2, 10000);
  if (section->Has("width")) {
    curve->width = section->InRange("width", section->RequiredNumber("width"), 0.0, 1.0);
    if (curve->width == 0.0) section->Fail("width", "must be > 0");
  }
}

}  // namespace

CouplingStudy LoadCouplingStudy(const std::string& path, const driveline::Scene& scene) {
  const toml::table root = LoadTomlFile(path);
  const TomlSection top(root, path, "");
  top.RequireOnlyKeys(
      {"objective", "variable", "twist_limit", "frequency_limit", "optimizer", "curve"});
  CouplingStudy study;
  CouplingProblem& problem = study.problem;
  problem.file = path;
  problem.counted_links = sweep::AllLinks(scene);
  if (const auto objective = top.OptionalTable("objective")) {
    objective->RequireOnlyKeys({"links"});
    if (objective->Has("links")) {
      problem.counted_links = sweep::ReadLinkNames(*objective, "links", scene);
    }
  }
  ReadVariables(top, scene, &problem);
  ReadTwistLimits(top, scene, &problem);
  if (const auto frequency = top.OptionalTable("frequency_limit")) {
    frequency->RequireOnlyKeys({"min_frequency"});
    problem.min_frequency_Hz =
        frequency->Positive("min_frequency", frequency->RequiredNumber("min_frequency"));
  }
  ReadOptimizer(top, &study.options);
  ReadCurve(top, &study.curve);
  return study;
}

}  // namespace millkit::coupling
