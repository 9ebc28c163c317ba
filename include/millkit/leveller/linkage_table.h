// Linkage kinematics over a table of poses (`millkit leveller forward|inverse`, docs/leveller.md):
// the working-range checks of a pose, the forward map of every row of a CSV table, and the CSV
// writers of the forward and inverse results. The inverse table itself is computed by the NLopt
// layer (millkit/optimize/leveller/inverse_table.h): it names the nearest reachable pair of a
// target out of reach, which takes an optimiser.
//
// Output CSV: the input columns (values rewritten with 15 significant digits: enough to carry the
// 1e-9 mm inverse accuracy through a file), then
//   forward:            y1_mm, y2_mm, y3_mm
//   inverse, eccentric: beta1_deg, beta2_deg, y3_mm, residual_mm, accuracy_mm,
//                       nearest_y1_mm, nearest_y2_mm, status
//   inverse, hydraulic: ah_mm, bg_mm, y3_mm, residual_mm, nearest_y1_mm, nearest_y2_mm, status
// An input column named like an output column is an InputError.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "millkit/io/csv.h"
#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/linkage.h"

namespace millkit::leveller {

// How the linkage is driven: eccentric angles beta1_deg, beta2_deg, or (hydraulic variant) the
// cylinder lengths ah_mm, bg_mm.
enum class LinkageDrive { kEccentric, kHydraulic };

// Throws InputError "<where>: column 'beta1_deg' = v outside the working range [min, max] deg"
// (beta1_deg checked first, then beta2_deg).
void CheckWorkingRange(const LinkageGeometry& geometry, double beta1_deg, double beta2_deg,
                       const std::string& where);
// Throws InputError "<where>: (ah_mm, bg_mm) = (u, v) outside the cylinder ranges [..] x [..] mm".
void CheckCylinderRanges(const HydraulicRange& cylinders, double ah_mm, double bg_mm,
                         const std::string& where);

// Throws InputError "<source>: column '<c>' is an output column; remove it" for the first of
// `outputs` that `input` has.
void RequireNoOutputColumns(const CsvTable& input, const std::vector<std::string>& outputs);
// Throws InputError when the table has a header and no row: a list of `what` was expected (an
// empty file or the wrong one, as `leveller table` says of a strip list with no strip).
void RequireRows(const CsvTable& input, const std::string& what);

// "<source>:<line>" of data row `row`, the prefix of every message about that row.
std::string RowLocation(const CsvTable& table, std::size_t row);

struct ForwardTable {
  CsvTable input;
  std::vector<Intermesh<double>> intermesh;  // one per input row
};

// The forward map of every row of `input` (columns beta1_deg, beta2_deg; hydraulic: ah_mm, bg_mm).
// Throws InputError naming the file and line: a missing input column, an output column in the
// input, a pose outside the working range (cylinder ranges), a pose that does not assemble.
ForwardTable ComputeForwardTable(const CsvTable& input, const LevellerConfig& config,
                                 LinkageDrive drive);

std::string FormatForwardTable(const ForwardTable& table);

// One target of the inverse table. Values are NaN where they do not apply.
struct InverseRow {
  static constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();
  // "ok"; "unreachable" (out of the linkage's reach: no angles, the nearest reachable pair when
  // one was found); "not_converged" (reachable, but the solver did not meet the target).
  std::string status = "ok";
  double beta1_deg = kNoValue;  // eccentric drive
  double beta2_deg = kNoValue;
  double ah_mm = kNoValue;  // hydraulic drive
  double bg_mm = kNoValue;
  double y3_mm = kNoValue;
  double residual_mm = kNoValue;
  double accuracy_mm = kNoValue;  // eccentric drive: max ΔY for the encoder resolution
  // The reachable pair nearest the target: the target itself when ok.
  double nearest_y1_mm = kNoValue;
  double nearest_y2_mm = kNoValue;
  // Messages for the user, without the "<file>:<line>: " prefix (RowLocation).
  std::vector<std::string> warnings;

  bool ok() const { return status == "ok"; }
};

struct InverseTable {
  CsvTable input;
  LinkageDrive drive = LinkageDrive::kEccentric;
  std::vector<InverseRow> rows;  // one per input row
  int NotOkCount() const;
};

// The columns the inverse adds to the input, in order (see the file comment).
std::vector<std::string> InverseOutputColumns(LinkageDrive drive);

std::string FormatInverseTable(const InverseTable& table);

}  // namespace millkit::leveller
