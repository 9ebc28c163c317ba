// Drive-line scene: a tree of rigid inertias joined by torsional links with backlash, external
// torque sources and an optional speed drive (SPEC.md §2). SI units throughout: rad, s, N·m,
// kg·m², N·m/rad, N·m·s/rad.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "millkit/driveline/backlash_law.h"

namespace millkit::driveline {

struct Mass {
  std::string name;
  double inertia_kg_m2 = 0.0;  // > 0
};

// A link passes torque m(ψ, ψ') from `from` to `to`, with twist ψ = φ_from − φ_to (SPEC §2.1).
//
// Gear ratio (SPEC §1): a link with ratio i = ω_from / ω_to is a gear stage whose `from` side is
// given unreduced, in its own shaft's units. Its twist is ψ = φ_from / i − φ_to, measured on the
// `to` side, and its stiffness, damping and backlash are in `to`-side units; it passes torque m to
// the `to` mass and −m / i to the `from` mass (power balance). Every quantity of the masses and
// links beyond `from` (the part of the tree on the `from` side of the link) is in that side's
// units: their speeds are i times the `to`-side speeds, their torques 1/i times. Ratios compose
// along the tree. A solver works on ReducedScene (all on the reference shaft: the masses beyond
// no ratio link) and reports every output in the units of the object it belongs to.
struct Link {
  std::string name;
  int from = -1;                      // mass index
  int to = -1;                        // mass index
  double stiffness_Nm_per_rad = 0.0;  // c > 0
  double damping_Nms_per_rad = 0.0;   // d >= 0
  double backlash_rad = 0.0;          // b >= 0, TOTAL clearance; dead zone |ψ| <= b/2
  double gap_position = -1.0;         // in [-1, 1]: rest twist = gap_position·b/2 without torque
  double ratio = 1.0;                 // i = ω_from / ω_to > 0; 1: no gear
  // Not a scene key: set by a fit whose channel on this link records through a first-order
  // anti-alias low-pass, y' = 2π f_c (m − y), settled at t = 0. When > 0 the model carries y as
  // a state and reports it as the link's torque (outputs, peaks, sensitivities; a link made rigid
  // reports that over c as its twist), exactly at any output time; 0: the link's own torque.
  double recorder_lowpass_Hz = 0.0;
};

// A piecewise-linear torque on one mass (SPEC §2.3): knots (time, value), linear between knots,
// held constant outside them. Two knots at the same time make a step; the value at the step time
// is the later one (right-continuous). A ramp `before → after` over [start, start + rise] is the
// knots {(start, before), (start + rise, after)}.
struct TorqueSource {
  std::string name;  // for messages, e.g. "[[torque]] #1 at upper_roll"
  int mass = -1;
  std::vector<double> times_s;
  std::vector<double> values_Nm;

  double ValueAt(double t) const;
  // Slope on the segment that starts at t (right derivative).
  double SlopeAt(double t) const;
};

// PI speed controller with a first-order torque lag (SPEC §2.3, seed 000 fig. 6):
// u = kp (ω_ref − ω) + ki ∫(ω_ref − ω) dt, clipped to ±limit;  T_e M' = u − M.
struct Drive {
  int mass = -1;
  double speed_ref_rad_per_s = 0.0;
  double kp = 0.0;        // N·m·s/rad, >= 0
  double ki = 0.0;        // N·m/rad, >= 0
  double lag_s = 0.0;     // T_e > 0
  double limit_Nm = 0.0;  // > 0
};

struct Scene {
  std::string name;
  std::string file;  // where it was loaded from (for messages)
  double duration_s = 0.0;
  double sample_rate_Hz = 0.0;
  ContactLaw contact = ContactLaw::kLimited;
  double initial_speed_rad_per_s = 0.0;  // of the reference shaft (k = 1 below)
  std::optional<double> band_Hz;         // band-limited reduction (SPEC §2.7); none when absent
  std::vector<Mass> masses;
  std::vector<Link> links;
  std::vector<TorqueSource> torques;
  std::optional<Drive> drive;

  int MassIndex(const std::string& name) const;  // -1 when absent
  int LinkIndex(const std::string& name) const;  // -1 when absent
  // Every time in (0, duration) where an input torque changes slope or jumps, sorted, unique.
  std::vector<double> InputBreakpoints() const;
  // Number of output samples: floor(duration · sample_rate) + 1, the first at t = 0.
  int SampleCount() const;
};

// The twist (rad) of a link carrying a steady torque T with its gap closed on the loaded flank:
// b/2 + |T|/c (its magnitude; the sign is the torque's).
double QuasiStaticTwist(const Link& link, double torque_Nm);

// Shaft factors of a scene with gear ratios: k of a mass is the product of the ratios of the links
// it lies beyond (on whose `from` side it is), 1 on the reference shaft; k of a link is that of its
// `to` mass (a link's own quantities are in its `to`-side units). A quantity in an object's units
// reduces to the reference shaft as: speed ω/k, angle φ/k, torque T·k, inertia, stiffness and
// damping ·k², PI gains kp, ki ·k². Requires a tree (ValidateScene).
struct ShaftFactors {
  std::vector<double> mass;  // per scene mass
  std::vector<double> link;  // per scene link
  bool identity = true;      // every ratio is 1
};
ShaftFactors ComputeShaftFactors(const Scene& scene);

// The scene with every quantity reduced to the reference shaft and every ratio 1 (a copy of the
// scene when it has no ratio). Its outputs convert back with the factors: speed ·k_mass, link
// torque /k_link, twist ·k_link.
Scene ReducedScene(const Scene& scene);

// Loads and validates a scene TOML (SPEC §2.6). Throws InputError naming the file, the key and
// the rule for: TOML syntax, unknown keys, missing keys, unknown or repeated names, a link to
// itself, a topology that is not a tree, non-positive inertia or stiffness, negative damping or
// backlash, gap_position outside [−1, 1], a ratio that is not > 0, unknown contact law, bad torque
// tables, a drive with bad gains, and a sample rate that cannot resolve the fastest mode of the
// model it will run.
Scene LoadScene(const std::string& path);

// Checks the rules above on a scene built in code (LoadScene calls it). Throws InputError.
void ValidateScene(const Scene& scene);

}  // namespace millkit::driveline
