// Setpoint tables (issue 4, `millkit leveller table`): per strip grade and size, the intermesh from
// the strip mechanics (strip_mechanics.h), the eccentric angles from the closed-form inverse
// (linkage.h), forces, torque and power (roll_forces.h), the setpoint accuracy for an encoder
// resolution, and warnings: machine limits (roll force, total force, motor power), stroke (target
// outside the linkage's reach), roll collision, dead centre, setpoint solve not converged.
//
// Strip list CSV (numeric, header row):
//   required: yield_mpa, thickness_mm, width_mm, entry_plastic_ratio (fraction of h yielded at
//             roll 2, [0, 1))
//   optional: youngs_mpa (default 2.1e5), exit_curvature_ratio (present: C at roll 6 is fixed;
//             absent: the exit is flat)
#pragma once

#include <string>
#include <vector>

#include "millkit/io/csv.h"
#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/linkage.h"
#include "millkit/leveller/strip_mechanics.h"

namespace millkit::leveller {

struct StripCase {
  Strip strip;
  SetpointOptions setpoint;
  int line = 0;  // line in the strip list (1-based)
};

// Validates every row; InputError names the file, line, column and the rule (e.g. thickness ≤ 0).
std::vector<StripCase> ReadStripCases(const CsvTable& table);

struct TableOptions {
  double encoder_deg = 0.01;             // eccentric encoder resolution Δβ
  double dead_centre_warning_deg = 5.0;  // warn when β is this close to a dead centre
  // Throws InputError naming the option.
  void Validate() const;
};

struct TableRow {
  StripCase input;
  StripSetpoint setpoint;
  AngleSetpoint angles;      // status != kOk: stroke warning, angles not valid
  double accuracy_mm = 0.0;  // max ΔY over the three upper rolls (NaN if unreachable)
  std::vector<std::string> warnings;

  // "ok"; "unreachable" (the intermesh is out of the linkage's reach: no angles); or
  // "not_converged" (the strip solve did not converge). Limit warnings leave a row ok.
  std::string Status() const;
};

std::vector<TableRow> ComputeSetpointTable(const std::vector<StripCase>& cases,
                                           const LevellerConfig& config,
                                           const TableOptions& options);

// CSV text of the table (header + one line per row; status, then warnings joined by "; ", no
// commas).
std::string FormatSetpointTable(const std::vector<TableRow>& rows);

}  // namespace millkit::leveller
