#include "millkit/leveller/setpoint_table.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::leveller {
namespace {

// Setpoint cells: 10 significant digits; "nan" for anything not finite.
std::string Cell(double value) { return std::isfinite(value) ? ShortNumber(value, 10) : "nan"; }

}  // namespace

std::vector<StripCase> ReadStripCases(const CsvTable& table) {
  const int yield = table.Column("yield_mpa");
  const int thickness = table.Column("thickness_mm");
  const int width = table.Column("width_mm");
  const int entry = table.Column("entry_plastic_ratio");
  const int youngs = table.HasColumn("youngs_mpa") ? table.Column("youngs_mpa") : -1;
  const int exit =
      table.HasColumn("exit_curvature_ratio") ? table.Column("exit_curvature_ratio") : -1;
  if (table.rows.empty()) throw InputError(table.source + ": no strips listed");
  std::vector<StripCase> cases;
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    const auto& row = table.rows[r];
    const std::string where = table.source + ":" + std::to_string(table.line_numbers[r]);
    auto positive = [&](int column) {
      const double v = row[column];
      if (!(v > 0.0)) {
        throw InputError(where + ": column '" + table.columns[column] + "' must be > 0 (got " +
                         FormatNumber(v) + ")");
      }
      return v;
    };
    StripCase c;
    c.line = table.line_numbers[r];
    c.strip.yield_MPa = positive(yield);
    c.strip.thickness_mm = positive(thickness);
    c.strip.width_mm = positive(width);
    if (youngs >= 0) c.strip.youngs_MPa = positive(youngs);
    c.setpoint.entry_plastic_ratio = row[entry];
    if (!(row[entry] >= 0.0 && row[entry] < 1.0)) {
      throw InputError(where + ": column 'entry_plastic_ratio' must be in [0, 1) (got " +
                       FormatNumber(row[entry]) + ")");
    }
    if (exit >= 0) {
      c.setpoint.exit = ExitCondition::kFixedCurvature;
      c.setpoint.exit_curvature_ratio = row[exit];
    }
    try {
      c.setpoint.Validate();
    } catch (const InputError& e) {
      throw InputError(where + ": " + e.what());
    }
    cases.push_back(c);
  }
  return cases;
}

void TableOptions::Validate() const {
  if (!(std::isfinite(encoder_deg) && encoder_deg > 0.0)) {
    throw InputError::Option("TableOptions", "encoder_deg",
                             "must be > 0 (got " + FormatNumber(encoder_deg) + ")");
  }
  if (!(dead_centre_warning_deg >= 0.0)) {
    throw InputError("dead-centre warning band must be >= 0 deg");
  }
}

std::vector<TableRow> ComputeSetpointTable(const std::vector<StripCase>& cases,
                                           const LevellerConfig& config,
                                           const TableOptions& options) {
  options.Validate();
  const Linkage linkage(config.linkage);
  std::vector<TableRow> rows;
  for (const auto& c : cases) {
    TableRow row;
    row.input = c;
    row.setpoint = ComputeStripSetpoint(c.strip, config.machine, c.setpoint);
    const auto& s = row.setpoint;
    if (!s.summary.converged) row.warnings.push_back("setpoint: " + s.summary.BriefReport());
    const auto limits = CheckMachineLimits(s.forces_kN, s.power_kW, config.machine);
    row.warnings.insert(row.warnings.end(), limits.begin(), limits.end());
    for (int k = 0; k < 3; ++k) {
      if (s.intermesh_mm[k] > s.collision_limit_mm) {
        row.warnings.push_back("roll collision: Y" + std::to_string(k + 1) + " = " +
                               FixedNumber(s.intermesh_mm[k], 3) + " mm > limit " +
                               FixedNumber(s.collision_limit_mm, 3) + " mm");
      }
    }
    row.angles = linkage.InverseClosedForm(s.intermesh_mm[0], s.intermesh_mm[1]);
    if (!row.angles.ok()) {
      row.warnings.push_back("stroke: Y1 = " + FixedNumber(s.intermesh_mm[0], 3) +
                             " mm and Y2 = " + FixedNumber(s.intermesh_mm[1], 3) +
                             " mm outside the linkage reach (" + ToString(row.angles.status) + ")");
      row.accuracy_mm = std::numeric_limits<double>::quiet_NaN();
    } else {
      const auto accuracy =
          linkage.Accuracy(row.angles.beta1_deg, row.angles.beta2_deg, options.encoder_deg);
      row.accuracy_mm = accuracy.max_delta_y_mm;
      if (accuracy.dead_centre_distance_deg < options.dead_centre_warning_deg) {
        row.warnings.push_back("dead centre: eccentric within " +
                               FixedNumber(accuracy.dead_centre_distance_deg, 3) + " deg");
      }
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

std::string TableRow::Status() const {
  if (!setpoint.summary.converged) return "not_converged";
  return angles.ok() ? "ok" : "unreachable";
}

std::string FormatSetpointTable(const std::vector<TableRow>& rows) {
  std::string text =
      "line,yield_mpa,youngs_mpa,thickness_mm,width_mm,entry_plastic_ratio,y1_mm,y2_mm,y3_mm,"
      "beta1_deg,beta2_deg,p1_kN,p2_kN,p3_kN,p4_kN,p5_kN,p6_kN,p7_kN,total_force_kN,torque_kNm,"
      "power_kW,exit_residual_curvature_ratio,accuracy_mm,status,warnings\n";
  for (const auto& row : rows) {
    const auto& s = row.setpoint;
    const bool ok = row.angles.ok();
    std::vector<double> cells = {static_cast<double>(row.input.line),
                                 row.input.strip.yield_MPa,
                                 row.input.strip.youngs_MPa,
                                 row.input.strip.thickness_mm,
                                 row.input.strip.width_mm,
                                 row.input.setpoint.entry_plastic_ratio,
                                 s.intermesh_mm[0],
                                 s.intermesh_mm[1],
                                 s.intermesh_mm[2],
                                 ok ? row.angles.beta1_deg : std::nan(""),
                                 ok ? row.angles.beta2_deg : std::nan("")};
    for (double p : s.forces_kN) cells.push_back(p);
    cells.insert(cells.end(), {s.total_force_kN, s.straightening_torque_kNm, s.power_kW,
                               s.exit_residual_curvature_ratio, row.accuracy_mm});
    for (double v : cells) text += Cell(v) + ",";
    text += row.Status() + ",";
    std::string warnings;
    for (const auto& w : row.warnings) warnings += (warnings.empty() ? "" : "; ") + w;
    std::replace(warnings.begin(), warnings.end(), ',', ' ');
    text += warnings + "\n";
  }
  return text;
}

}  // namespace millkit::leveller
