// Inputs of the spindle balancing device calculator (SPEC.md §7, seed 002) and of the idle-gap
// rule (seed 000). SI throughout (N, m, Pa); angles in degrees at this interface because the seed
// and its users state them so, converted to radians inside the models.
//
// Every default is the seed's case: the roller-supported hydraulic balancer of the spindles of the
// 950 stand (seed 002, sections 1, 2, 3, 4 and 6). Where the seed's printed number and its stated
// data disagree, the default is the reading that reproduces the printed number, and the comment
// says so; datasets/balancer/README.md lists every value with its source.
//
// A TOML file describes one device completely (datasets/balancer/seed_002_stand950.toml is the
// seed's case): every section and every key below is required, so a forgotten key is an error and
// never silently the seed's value. Rules on values (sign, range, the angle rule cos(α + 2β) > 0)
// live in FindInputViolation() alone; the TOML reader and Validate() both report through it.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace millkit::balancer {

// Loads on the device (seed 002 §1 and §6).
struct DeviceLoads {
  // Q: load acting on one balancing (roller) support, N. Seed 002 §1: Q = 111.53 kN.
  double support_load_N = 111530.0;
  // G: share of the spindle weight carried by one rod of the balancer (cardan cross), N.
  // Seed 002 §6: G = 90 700.8 N. The seed's contact check (§3) also uses G + Q as "the pressure
  // force of the spindle shaft"; we read that G as the same value (the seed names no other G).
  double rod_weight_share_N = 90700.8;
};

// Roller support of the spindle shaft (seed 002 §1, fig. 3; the figure is not available).
struct SupportGeometry {
  // α: angle between the vertical and the roller axis, deg. Seed 002 §1: 30°. Valid [0, 90).
  double alpha_deg = 30.0;
  // lp: centre distance of the rollers, m. Seed 002 §1: 190 mm.
  double roller_spacing_m = 0.190;
  // D: diameter of the spindle shaft, m. Seed 002 §1: 600 mm.
  double shaft_diameter_m = 0.600;
  // β = arctan(lp/D) = 17.571° is printed as 17.5° and P1 = 65 975.6 N follows only from 17.5°
  // (the exact angle gives 66 329.6 N). Reading: the seed rounds β to the nearest half degree.
  // β is rounded to the nearest multiple of this step, deg; 0 uses the exact angle. Valid [0, 5].
  double beta_rounding_deg = 0.5;
};

// The support roller as a simply supported beam (seed 002 §2, fig. 4): supports N1, N2 at the
// ends, the shaft's load P1 spread uniformly over the middle length 2b, a clear length a between
// each support and the loaded length. Span 2a + 2b.
struct RollerBeam {
  // a, m. Seed 002 §2: 0.084 m (section x1 = 84 mm).
  double support_offset_m = 0.084;
  // b: half of the loaded length, m. Seed 002 §2: 0.245 m; q = P1 / (2 · 0.245) = P1 / 0.490.
  double half_loaded_length_m = 0.245;
};

// Contact (crushing) check of a roller on the shaft (seed 002 §3).
struct RollerContact {
  // Adopted roller diameter, m. Seed 002 §3: d = 100 mm, r = 0.05 m.
  double diameter_m = 0.100;
  // Roller width b of the line contact, m. Seed 002 §3: 0.06 m.
  double width_m = 0.060;
  // Number of rollers sharing G + Q. Seed 002 §3: 8. >= 1 (an integer in TOML).
  int count = 8;
  // E_пр: reduced modulus of a steel roller on a steel shaft, Pa. The seed prints 2.1·10^9 Pa, a
  // garbled exponent: E_пр of steel on steel is E = 2.1·10^11 Pa (2.1·10^5 MPa), the value the
  // coefficient 0.418 of the line-contact formula is written for.
  double elastic_modulus_Pa = 2.1e11;
  // [σсм], Pa. The seed prints 8.5 MPa and states that the check passes; with the seed's own data
  // the stress is 629 MPa (62.9 MPa even with the garbled E), so the printed value cannot be the
  // limit the seed checked against. Reading: 8.5·10² MPa = 850 MPa (lost "·10²"), a usual limit
  // for hardened steel rollers in line contact; with it the seed's conclusion holds.
  double allowable_stress_Pa = 850.0e6;
  // k: factor of the operating mode of the mechanism. Seed 002 §3: 1.6.
  double duty_factor = 1.6;
  // γ: factor of the load variability. Seed 002 §3: 0.8.
  double load_variability_factor = 0.8;
};

// Axle of a roller pair as a beam on two hinged supports (the middles of its plain bearings) with
// the forces N3, N4 on overhangs beyond each support (seed 002 §4, figs. 5 and 6).
struct RollerAxle {
  // b: distance between the axle supports, m. Seed 002 §4: 0.34 m.
  double support_span_m = 0.34;
  // a: overhang of N3 and N4 beyond the supports, m. The seed states x = a = 161.5 mm but
  // multiplies by 0.161 m, and the printed M = 6644.7 N·m follows only from 0.161 m (0.1615 m
  // gives 6665.3 N·m, +0.31 %). The seed's case takes the seed's arithmetic: 0.161 m.
  double overhang_m = 0.161;
};

// Cross of the cardan joint between a balancer rod and the traverse (seed 002 §6, figs. 7 and 8).
struct CardanCross {
  // Arm of the reaction N on the largest pin, m. Seed 002 §6: 0.156 m.
  double pin_arm_m = 0.156;
  // Adopted pin diameter, m. Seed 002 §6: 75 mm.
  double pin_diameter_m = 0.075;
  // σв: ultimate tensile strength, Pa. Seed 002 §6: 1370 MPa, steel 40ХН quenched and tempered.
  double ultimate_strength_Pa = 1370.0e6;
  // S1 (reliability of loads and stresses, seed range 1…1.5), S2 (uniformity of material, seed
  // range 1.2…1.5), S3 (safety requirements, seed range 1…1.5). The seed does not say which values
  // it took; the default is the top of each range (S = 3.375), our conservative choice. Each >= 1.
  double s1 = 1.5;
  double s2 = 1.5;
  double s3 = 1.5;
};

// Balancing setting of the spindle and the idle-gap rule (seed 000; see idle_gap_rule.h).
struct BalanceSetting {
  // Force that balances the spindle exactly, N. Default: Q, the load the seed's support is
  // designed for (seed 002 §1).
  double required_force_N = 111530.0;
  // Force the balancer is set to, N. Default: exact balance.
  double balancing_force_N = 111530.0;
  // Seed 000: only a setting within ±3…5 % of exact balance takes up the gaps of both spindle
  // hinges at idle. Deviations up to the first bound keep the gaps closed, beyond the second they
  // open; in between they open and close as the hinge turns. Percent, 0 <= closed <= open.
  double closed_within_percent = 3.0;
  double open_beyond_percent = 5.0;
};

struct BalancerInput {
  DeviceLoads loads;
  SupportGeometry support;
  RollerBeam roller;
  RollerContact contact;
  RollerAxle axle;
  CardanCross cross;
  BalanceSetting balance;
};

// The seed's case (seed 002, SPEC.md §7): the defaults above.
BalancerInput SeedCase();

// A broken rule: TOML section, key, and the rule with the offending value.
struct InputViolation {
  std::string section;
  std::string key;
  std::string rule;
};

// The first broken rule, or nullopt. Rules: loads > 0; lengths > 0 (overhangs and offsets >= 0);
// 0 <= α < 90° and α + 2β < 90° (so that cos(α + 2β) > 0 and cos(α + β) > 0); the rounding step of
// β in [0, 5]°; roller count >= 1; moduli, strengths and factors > 0; S1, S2, S3 >= 1;
// balancing force >= 0; 0 <= closed_within_percent <= open_beyond_percent.
std::optional<InputViolation> FindInputViolation(const BalancerInput& input);

// Throws InputError "balancer input: [section] key 'k': rule" on the first broken rule.
void Validate(const BalancerInput& input);

// Table and key names of the TOML layout, in order; used by the reader, the writer and the
// command line's --set.
const std::vector<std::pair<std::string, std::vector<std::string>>>& TomlLayout();
// True when `section` is a table of the layout and, if `key` is not empty, `key` is one of its
// keys.
bool TomlLayoutHas(std::string_view section, std::string_view key = {});

// Reads a complete device description from a TOML file (the layout of TomlLayout()). Throws
// InputError naming the file, table, key and line: a file that cannot be read or parsed, unknown
// table or key, missing table or key, a value that is not a number, and every rule of
// FindInputViolation(). (The reader of an already parsed document is private:
// src/balancer/balancer_toml.h.)
BalancerInput ReadBalancerInputFile(const std::filesystem::path& path);

}  // namespace millkit::balancer
