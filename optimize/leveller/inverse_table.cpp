#include "millkit/optimize/leveller/inverse_table.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::leveller {
namespace {

// A row that is not ok: its status, the reason, and (out of reach) the nearest reachable pair.
InverseRow FailedRow(const Linkage& linkage, const std::string& status, double y1, double y2,
                     bool name_nearest, const std::string& why, const HydraulicRange* cylinders) {
  InverseRow row;
  row.status = status;
  std::string message = status + ": " + why;
  const ReachablePoint nearest =
      name_nearest ? NearestReachableInside(linkage, y1, y2, cylinders) : ReachablePoint{};
  if (name_nearest && !std::isfinite(nearest.distance_mm)) {
    message += "; no reachable pair was found near it";
  } else if (name_nearest) {
    row.nearest_y1_mm = nearest.y1_mm;
    row.nearest_y2_mm = nearest.y2_mm;
    char buffer[160];
    if (cylinders != nullptr) {
      std::snprintf(buffer, sizeof(buffer),
                    "; nearest reachable (y1_mm, y2_mm) = (%.6f, %.6f) at (ah_mm, bg_mm) = "
                    "(%.4f, %.4f)",
                    nearest.y1_mm, nearest.y2_mm, nearest.ah_mm, nearest.bg_mm);
    } else {
      std::snprintf(buffer, sizeof(buffer),
                    "; nearest reachable (y1_mm, y2_mm) = (%.6f, %.6f) at beta = (%.4f, %.4f) "
                    "deg",
                    nearest.y1_mm, nearest.y2_mm, nearest.beta1_deg, nearest.beta2_deg);
    }
    message += buffer;
  }
  row.warnings.push_back(message);
  return row;
}

InverseRow HydraulicRow(const Linkage& linkage, const HydraulicRange& cylinders, double y1,
                        double y2) {
  const LengthSetpoint lengths = linkage.InverseLengths(y1, y2, cylinders);
  if (!lengths.ok()) {
    return FailedRow(linkage, "unreachable", y1, y2, true,
                     "target (" + FormatNumber(y1) + ", " + FormatNumber(y2) +
                         ") is not reachable by the cylinders (" + ToString(lengths.status) + ")",
                     &cylinders);
  }
  InverseRow row;
  row.ah_mm = lengths.ah_mm;
  row.bg_mm = lengths.bg_mm;
  row.y3_mm = lengths.y3_mm;
  row.residual_mm = lengths.residual_mm;
  // A reachable target is its own nearest reachable pair.
  row.nearest_y1_mm = y1;
  row.nearest_y2_mm = y2;
  return row;
}

InverseRow EccentricRow(const Linkage& linkage, const NloptInverse& nlopt_inverse,
                        const InverseTableOptions& options, double y1, double y2) {
  const AngleSetpoint closed = linkage.InverseClosedForm(y1, y2);
  if (closed.status != InverseStatus::kOk && closed.status != InverseStatus::kAssemblyMismatch) {
    return FailedRow(linkage, "unreachable", y1, y2, true,
                     "target (" + FormatNumber(y1) + ", " + FormatNumber(y2) +
                         ") is outside the linkage's reach (" + ToString(closed.status) + ")",
                     nullptr);
  }
  InverseRow row;
  row.beta1_deg = closed.beta1_deg;
  row.beta2_deg = closed.beta2_deg;
  row.y3_mm = closed.y3_mm;
  row.residual_mm = closed.residual_mm;
  if (options.method == InverseMethod::kNlopt) {
    const NloptInverseResult solved = nlopt_inverse.Solve(y1, y2);
    if (!solved.summary.accepted) {
      return FailedRow(linkage, "not_converged", y1, y2, false, solved.summary.BriefReport(),
                       nullptr);
    }
    row.beta1_deg = solved.beta1_deg;
    row.beta2_deg = solved.beta2_deg;
    row.y3_mm = solved.y3_mm;
    row.residual_mm = solved.summary.residual_mm;
    if (closed.ok() && solved.summary.closed_form_difference_deg > 1e-6) {
      row.warnings.push_back("NLopt and closed form differ by " +
                             FormatNumber(solved.summary.closed_form_difference_deg) +
                             " deg (both meet the target; the pose is near a dead centre)");
    }
  } else if (!closed.ok()) {
    return FailedRow(linkage, "not_converged", y1, y2, false,
                     "closed form: " + ToString(closed.status), nullptr);
  }
  const SetpointAccuracy accuracy =
      linkage.Accuracy(row.beta1_deg, row.beta2_deg, options.encoder_deg);
  if (accuracy.dead_centre_distance_deg < options.dead_centre_warning_deg) {
    row.warnings.push_back("eccentric within " + FormatNumber(accuracy.dead_centre_distance_deg) +
                           " deg of a dead centre: dY/dbeta is small, the angle is poorly "
                           "determined");
  }
  row.accuracy_mm = accuracy.max_delta_y_mm;
  row.nearest_y1_mm = y1;
  row.nearest_y2_mm = y2;
  return row;
}

}  // namespace

void InverseTableOptions::Validate() const {
  if (!(std::isfinite(encoder_deg) && encoder_deg > 0.0)) {
    throw InputError::Option("InverseTableOptions", "encoder_deg",
                             "must be > 0 (got " + FormatNumber(encoder_deg) + ")");
  }
}

InverseTable ComputeInverseTable(const CsvTable& input, const LevellerConfig& config,
                                 const InverseTableOptions& options) {
  options.Validate();
  const Linkage linkage(config.linkage);
  const NloptInverse nlopt_inverse(linkage, options.nlopt);
  const int c1 = input.Column("y1_mm");
  const int c2 = input.Column("y2_mm");
  RequireNoOutputColumns(input, InverseOutputColumns(options.drive));
  RequireRows(input, "intermesh targets");
  InverseTable table{input, options.drive, {}};
  for (const auto& cells : input.rows) {
    const double y1 = cells[c1];
    const double y2 = cells[c2];
    table.rows.push_back(options.drive == LinkageDrive::kHydraulic
                             ? HydraulicRow(linkage, config.hydraulic, y1, y2)
                             : EccentricRow(linkage, nlopt_inverse, options, y1, y2));
  }
  return table;
}

ReachablePoint NearestReachableInside(const Linkage& linkage, double y1_mm, double y2_mm,
                                      const HydraulicRange* cylinders) {
  ReachablePoint nearest = cylinders != nullptr
                               ? NearestReachableByCylinders(linkage, y1_mm, y2_mm, *cylinders)
                               : NearestReachable(linkage, y1_mm, y2_mm);
  if (!std::isfinite(nearest.distance_mm)) return nearest;
  const double d1 = nearest.y1_mm - y1_mm;
  const double d2 = nearest.y2_mm - y2_mm;
  const double length = std::hypot(d1, d2);
  for (double step = 1e-6; step <= 1e-2; step *= 10.0) {
    const double u1 = length > 0.0 ? nearest.y1_mm + step * d1 / length : nearest.y1_mm;
    const double u2 = length > 0.0 ? nearest.y2_mm + step * d2 / length : nearest.y2_mm;
    const double r1 = std::round(u1 * 1e6) / 1e6;
    const double r2 = std::round(u2 * 1e6) / 1e6;
    if (cylinders != nullptr) {
      const LengthSetpoint check = linkage.InverseLengths(r1, r2, *cylinders);
      if (!check.ok()) continue;
      nearest.ah_mm = check.ah_mm;
      nearest.bg_mm = check.bg_mm;
    } else {
      const AngleSetpoint check = linkage.InverseClosedForm(r1, r2);
      if (check.status != InverseStatus::kOk && check.status != InverseStatus::kAssemblyMismatch) {
        continue;
      }
      nearest.beta1_deg = check.beta1_deg;
      nearest.beta2_deg = check.beta2_deg;
    }
    nearest.y1_mm = r1;
    nearest.y2_mm = r2;
    return nearest;
  }
  nearest.distance_mm = std::numeric_limits<double>::infinity();
  return nearest;
}

}  // namespace millkit::leveller
