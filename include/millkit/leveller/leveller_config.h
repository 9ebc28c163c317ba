// Leveller configuration: linkage geometry (SPEC.md §6.2), roll set and machine data (SPEC.md
// §6.1), read from a TOML file whose every key is optional and defaults to the SPEC value.
//
// Units at this interface: mm, degrees, kN, kW, MPa (SPEC.md §1); the physics converts inside.
//
// TOML layout (datasets/leveller/leveller_default.toml is the bundled default):
//   [linkage]   a_mm, b_mm, c_mm (fixed points, [x, y]); ak_mm (L7), bj_mm (L1) eccentric radii;
//               hk_mm (L6), gj_mm (L2) rods; cg_mm (L3) guide; e0_mm, f0_mm, g0_mm, h0_mm beam pins
//               in the zero pose; beta_min_deg, beta_max_deg working range.
//   [hydraulic] ah_min_mm, ah_max_mm, bg_min_mm, bg_max_mm: cylinder length ranges (seed fig. 5-6;
//               default L2 -/+ L1 and L6 -/+ L7, the seed's bound 525.913 <= |BG| <= 555.913).
//   [rolls]     diameter_mm (D), pitch_mm (t, same-row pitch), lower_y_mm (Yd), count (7).
//   [machine]   bearing_diameter_mm (d), rolling_friction_arm_mm (f), bearing_friction (mu),
//               speed_m_per_s (v), efficiency (eta), motor_power_kW, max_roll_force_kN,
//               max_total_force_kN.
// A geometry whose rods cannot close somewhere in the working range is rejected on load with an
// InputError naming the key (see FindLinkageDefect).
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>

namespace millkit::leveller {

struct Point2 {
  double x = 0.0;
  double y = 0.0;
};

// SPEC.md §6.2, default geometry. Coordinates in mm, x along the pass line, y up.
struct LinkageGeometry {
  Point2 a{150.0, 1190.913};  // eccentric shaft axis of K (drives rod HK)
  Point2 b{450.0, 1190.913};  // eccentric shaft axis of J (drives rod GJ)
  Point2 c{950.0, 650.0};     // guide pivot
  double ak_mm = 15.0;        // L7, eccentric radius of K
  double bj_mm = 15.0;        // L1, eccentric radius of J
  double hk_mm = 540.913;     // L6, rod HK
  double gj_mm = 540.913;     // L2, rod GJ
  double cg_mm = 500.0;       // L3, guide CG
  // Beam pins in the zero pose; they fix the rigid beam's shape (L4 = EG, L5 = EH, L8 = EF, α1,
  // α2).
  Point2 e0{100.0, 180.0};  // centre of upper roll 1#
  Point2 f0{300.0, 180.0};  // centre of upper roll 2#
  Point2 g0{450.0, 650.0};
  Point2 h0{150.0, 650.0};
  double beta_min_deg = -90.0;  // working range of β1 and β2 (degrees, CCW from +x)
  double beta_max_deg = 90.0;
  double roll_diameter_mm = 180.0;  // D (copied from [rolls])
  double lower_y_mm = 0.0;          // Yd, lower roll centres
};

// Hydraulic variant (seed fig. 5-6): cylinders with linear sensors set |AH| and |BG|.
struct HydraulicRange {
  double ah_min_mm = 540.913 - 15.0;
  double ah_max_mm = 540.913 + 15.0;
  double bg_min_mm = 540.913 - 15.0;  // seed: 525.913 <= |BG| <= 555.913
  double bg_max_mm = 540.913 + 15.0;
};

// SPEC.md §6.1: roll set and drive data; limits default to the seed's design case (h = 6 mm,
// b = 1900 mm, σs = 550 MPa: P3 = 376.2 kN, ΣP = 1524.32 kN, 110 kW motor).
struct MachineData {
  double roll_diameter_mm = 180.0;       // D
  double pitch_mm = 200.0;               // t, between rolls of the same row
  double bearing_diameter_mm = 135.4;    // d, bearing mean diameter
  double rolling_friction_arm_mm = 0.2;  // f (0.8 mm with slip)
  double bearing_friction = 0.005;       // μ (0.005 rolling, 0.01 needle, 0.05-0.07 plain)
  double speed_m_per_s = 2.0;            // v, maximum levelling speed
  double efficiency = 0.85;              // η, 0.85 ... 0.7
  double motor_power_kW = 110.0;
  double max_roll_force_kN = 376.2;
  double max_total_force_kN = 1524.32;
  int roll_count = 7;
};

struct LevellerConfig {
  LinkageGeometry linkage;
  HydraulicRange hydraulic;
  MachineData machine;
  std::string source = "<built-in SPEC.md §6.2 defaults>";
};

// A key whose value makes the linkage impossible, and the rule that is broken.
struct LinkageDefect {
  std::string key;   // e.g. "gj_mm"
  std::string rule;  // e.g. "rods GJ and CG cannot close at beta2 = 12 deg: ..."
};

// Checks that the linkage assembles (both circle intersections exist) over a grid of the working
// range that includes its corners and the dead centres, that the beam pins are distinct and that
// the working range lies within [-180°, 180°]. Returns the first defect found.
std::optional<LinkageDefect> FindLinkageDefect(const LinkageGeometry& geometry);

// Throws InputError "<where>: key '<key>': <rule>" when FindLinkageDefect finds a defect.
void ValidateLinkage(const LinkageGeometry& geometry, const std::string& where);

// Reads a configuration TOML. Every key is optional (default: SPEC value); unknown tables or keys,
// non-positive lengths, an efficiency outside (0, 1], and a degenerate linkage throw InputError
// naming the file, table, key and line.
LevellerConfig LoadLevellerConfig(const std::filesystem::path& path);

// The built-in default (SPEC.md §6.2), validated.
LevellerConfig DefaultLevellerConfig();

}  // namespace millkit::leveller
