// The inverse kinematics over a table of targets (`millkit leveller inverse`, docs/leveller.md):
// for every row (y1_mm, y2_mm) the eccentric angles, or with the hydraulic drive the cylinder
// lengths, with y3, the residual, the setpoint accuracy and a status. A target out of reach, or
// one the solver could not meet, gets its status (and, out of reach, the nearest reachable pair)
// instead of stopping the batch; the CSV writer is FormatInverseTable (leveller/linkage_table.h).
//
// Method choice, eccentric drive: the closed form first (it decides "unreachable"); then
//   kNlopt:      the NLopt solve (NloptInverse) gives the answer, cross-checked against the
//                closed form (warning when they differ by more than 1e-6 deg: a dead centre);
//   kClosedForm: the closed form's answer, "not_converged" unless its re-check passed.
// Hydraulic drive: the closed-form cylinder lengths (InverseLengths); the method is not used.
// Warnings (InverseRow::warnings): the reason a row is not ok, the NLopt / closed-form
// difference, an eccentric within dead_centre_warning_deg of a dead centre.
#pragma once

#include "millkit/io/csv.h"
#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/linkage.h"
#include "millkit/leveller/linkage_table.h"
#include "millkit/optimize/leveller/nlopt_inverse.h"

namespace millkit::leveller {

enum class InverseMethod { kNlopt, kClosedForm };

struct InverseTableOptions {
  LinkageDrive drive = LinkageDrive::kEccentric;
  InverseMethod method = InverseMethod::kNlopt;
  NloptInverseOptions nlopt;             // kNlopt
  double encoder_deg = 0.01;             // eccentric encoder resolution Δβ for accuracy_mm
  double dead_centre_warning_deg = 5.0;  // warn when β is this close to a dead centre
  // Throws InputError naming the option (encoder_deg must be finite and > 0).
  void Validate() const;
};

// Every row of `input` (columns y1_mm, y2_mm). Throws InputError for invalid options, a missing
// input column or an output column in the input; a row that is not ok does not throw.
InverseTable ComputeInverseTable(const CsvTable& input, const LevellerConfig& config,
                                 const InverseTableOptions& options);

// The reachable pair nearest to (y1, y2) (by the eccentrics, or by the cylinders when `cylinders`
// is given), rounded to 1e-6 mm inward: moved past the boundary towards the inside (away from the
// target) until the rounded pair itself is reachable, so that typed back as a target it is
// accepted. distance_mm is infinite when no such pair was found.
ReachablePoint NearestReachableInside(const Linkage& linkage, double y1_mm, double y2_mm,
                                      const HydraulicRange* cylinders);

}  // namespace millkit::leveller
