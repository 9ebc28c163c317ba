#include "millkit/driveline/scene_parameter.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "millkit/io/input_error.h"

namespace millkit::driveline {
namespace {

double SummedLoadAtEnd(const Scene& scene, int mass) {
  double total = 0.0;
  for (const auto& source : scene.torques) {
    if (source.mass == mass) total += source.ValueAt(scene.duration_s);
  }
  return total;
}

double EarliestKnot(const Scene& scene) {
  double earliest = std::numeric_limits<double>::infinity();
  for (const auto& source : scene.torques) {
    if (!source.times_s.empty()) earliest = std::min(earliest, source.times_s.front());
  }
  return earliest;
}

}  // namespace

double SceneParameter::Get(const Scene& scene) const {
  switch (kind) {
    case Kind::kStiffness:
      return scene.links[index].stiffness_Nm_per_rad;
    case Kind::kDamping:
      return scene.links[index].damping_Nms_per_rad;
    case Kind::kBacklash:
      return scene.links[index].backlash_rad;
    case Kind::kGapPosition:
      return scene.links[index].gap_position;
    case Kind::kInertia:
      return scene.masses[index].inertia_kg_m2;
    case Kind::kLoad:
      return SummedLoadAtEnd(scene, index);
    case Kind::kBiteTime:
      return EarliestKnot(scene);
  }
  return 0.0;
}

void SceneParameter::Set(double value, Scene* scene) const {
  switch (kind) {
    case Kind::kStiffness:
      scene->links[index].stiffness_Nm_per_rad = value;
      return;
    case Kind::kDamping:
      scene->links[index].damping_Nms_per_rad = value;
      return;
    case Kind::kBacklash:
      scene->links[index].backlash_rad = value;
      return;
    case Kind::kGapPosition:
      scene->links[index].gap_position = value;
      return;
    case Kind::kInertia:
      scene->masses[index].inertia_kg_m2 = value;
      return;
    case Kind::kLoad: {
      const double current = SummedLoadAtEnd(*scene, index);
      if (current == 0.0) {
        throw InputError("parameter '" + name + "': mass '" + scene->masses[index].name +
                         "' carries no torque at the end of the run (a bite_time after the "
                         "duration?), so its load cannot be scaled");
      }
      const double factor = value / current;
      for (auto& source : scene->torques) {
        if (source.mass != index) continue;
        for (double& v : source.values_Nm) v *= factor;
      }
      return;
    }
    case Kind::kBiteTime: {
      const double shift = value - EarliestKnot(*scene);
      for (auto& source : scene->torques) {
        for (double& t : source.times_s) t += shift;
      }
      return;
    }
  }
}

SceneParameter ParseSceneParameter(const Scene& scene, const std::string& name,
                                   const std::string& where) {
  const std::string forms =
      "expected <link>.stiffness|damping|backlash|gap_position, <mass>.inertia|load, or "
      "bite_time";
  SceneParameter p;
  p.name = name;
  if (name == "bite_time") {
    if (!std::isfinite(EarliestKnot(scene))) {
      throw InputError(where + ": parameter 'bite_time' needs at least one [[torque]] source");
    }
    p.kind = SceneParameter::Kind::kBiteTime;
    p.unit = "s";
    return p;
  }
  const auto dot = name.rfind('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == name.size()) {
    throw InputError(where + ": unknown parameter '" + name + "' (" + forms + ")");
  }
  const std::string object = name.substr(0, dot);
  const std::string property = name.substr(dot + 1);
  struct LinkProperty {
    const char* name;
    SceneParameter::Kind kind;
    const char* unit;
  };
  static const LinkProperty kLinkProperties[] = {
      {"stiffness", SceneParameter::Kind::kStiffness, "N*m/rad"},
      {"damping", SceneParameter::Kind::kDamping, "N*m*s/rad"},
      {"backlash", SceneParameter::Kind::kBacklash, "rad"},
      {"gap_position", SceneParameter::Kind::kGapPosition, "1"},
  };
  for (const auto& lp : kLinkProperties) {
    if (property != lp.name) continue;
    p.index = scene.LinkIndex(object);
    if (p.index < 0) {
      throw InputError(where + ": unknown parameter '" + name + "': no link named '" + object +
                       "'");
    }
    p.kind = lp.kind;
    p.unit = lp.unit;
    return p;
  }
  if (property == "inertia" || property == "load") {
    p.index = scene.MassIndex(object);
    if (p.index < 0) {
      throw InputError(where + ": unknown parameter '" + name + "': no mass named '" + object +
                       "'");
    }
    if (property == "inertia") {
      p.kind = SceneParameter::Kind::kInertia;
      p.unit = "kg*m^2";
      return p;
    }
    p.kind = SceneParameter::Kind::kLoad;
    p.unit = "N*m";
    if (SummedLoadAtEnd(scene, p.index) == 0.0) {
      throw InputError(where + ": parameter '" + name + "': mass '" + object +
                       "' carries no torque at the end of the run, so there is no load to scale");
    }
    return p;
  }
  throw InputError(where + ": unknown parameter '" + name + "' (" + forms + ")");
}

ParameterRange PhysicalRange(SceneParameter::Kind kind) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  switch (kind) {
    case SceneParameter::Kind::kStiffness:
      return {0.0, kInf, false};
    case SceneParameter::Kind::kDamping:
    case SceneParameter::Kind::kBacklash:
      return {0.0, kInf, true};
    case SceneParameter::Kind::kGapPosition:
      return {-1.0, 1.0, true};
    case SceneParameter::Kind::kInertia:
      return {0.0, kInf, false};
    case SceneParameter::Kind::kLoad:
      return {-kInf, kInf, true};
    case SceneParameter::Kind::kBiteTime:
      return {0.0, kInf, true};
  }
  return {-kInf, kInf, true};
}

}  // namespace millkit::driveline
