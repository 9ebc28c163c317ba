// Test support: small scenes built in code (no files), and scene files written from text.
#pragma once

#include <string>

#include "millkit/driveline/simulation.h"

namespace millkit::driveline::testing {

inline constexpr double kPi = 3.14159265358979323846;

// max |a − b| / max |b|: disagreement relative to the reference's peak.
inline double RelativeDifference(const SampleMatrix& a, const SampleMatrix& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// Two masses joined by one link; no torque sources.
inline Scene TwoMassScene(double j1, double j2, double c, double d, double b, double duration,
                          double sample_rate, ContactLaw law = ContactLaw::kLimited) {
  Scene scene;
  scene.name = "two-mass";
  scene.duration_s = duration;
  scene.sample_rate_Hz = sample_rate;
  scene.contact = law;
  scene.masses = {{"a", j1}, {"b", j2}};
  Link link;
  link.name = "shaft";
  link.from = 0;
  link.to = 1;
  link.stiffness_Nm_per_rad = c;
  link.damping_Nms_per_rad = d;
  link.backlash_rad = b;
  scene.links = {link};
  return scene;
}

// A link from mass `from` to mass `to` (gap_position at its default, −1: resting on the negative
// flank).
inline Link MakeLink(const char* name, int from, int to, double c, double d, double b) {
  Link link;
  link.name = name;
  link.from = from;
  link.to = to;
  link.stiffness_Nm_per_rad = c;
  link.damping_Nms_per_rad = d;
  link.backlash_rad = b;
  return link;
}

// A step (or ramp) torque source on mass `mass`.
inline TorqueSource Step(int mass, double before, double after, double start, double rise = 0.0) {
  TorqueSource source;
  source.name = "test source";
  source.mass = mass;
  source.times_s = {start, start + rise};
  source.values_Nm = {before, after};
  return source;
}

}  // namespace millkit::driveline::testing
