// Named scalar parameters of a scene, shared by identification (issue 3), coupling optimisation
// and what-if sweeps (issue 5). A name is `<object>.<property>`:
//   <link>.stiffness   N·m/rad, > 0          <link>.damping       N·m·s/rad, >= 0
//   <link>.backlash    rad, >= 0 (total)     <link>.gap_position  in [−1, 1]
//   <mass>.inertia     kg·m², > 0
//   <mass>.load        N·m: the summed external torque on that mass at the end of the run
//                      (t = duration); setting it scales every torque source on the mass.
//   bite_time          s: the earliest knot of all torque sources (the load start); setting it
//                      shifts every torque source in time by the same amount.
// Setting a value does not validate the scene; Model's constructor does (ValidateScene).
#pragma once

#include <string>
#include <vector>

#include "millkit/driveline/scene.h"

namespace millkit::driveline {

struct SceneParameter {
  enum class Kind { kStiffness, kDamping, kBacklash, kGapPosition, kInertia, kLoad, kBiteTime };
  Kind kind = Kind::kDamping;
  int index = -1;    // link or mass index; −1 for bite_time
  std::string name;  // as the user wrote it
  std::string unit;  // for tables and plots

  double Get(const Scene& scene) const;
  // Throws InputError for a load on a mass whose final torque is zero (nothing to scale).
  void Set(double value, Scene* scene) const;
};

// Resolves a name against a scene. Throws InputError "<where>: unknown parameter '<name>' (...)",
// listing the accepted forms, for an unknown object or property, a load on a mass with no torque
// or a zero final torque, and bite_time in a scene without torque sources.
SceneParameter ParseSceneParameter(const Scene& scene, const std::string& name,
                                   const std::string& where);

// The physical range of a parameter kind (e.g. damping >= 0): lower, upper (±inf when open) and
// whether the lower bound itself is allowed. Used to reject user bounds outside it.
struct ParameterRange {
  double lower;
  double upper;
  bool lower_inclusive;
};
ParameterRange PhysicalRange(SceneParameter::Kind kind);

}  // namespace millkit::driveline
