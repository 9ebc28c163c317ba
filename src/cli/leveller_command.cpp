// `millkit leveller forward|inverse|forces|table` (issue 4, SPEC.md §6, §8). Parses, calls the
// leveller library, writes files atomically. No physics here.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/csv.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"
#include "millkit/io/output_files.h"
#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/linkage.h"
#include "millkit/leveller/roll_forces.h"
#include "millkit/leveller/setpoint_table.h"
#include "millkit/optimize/leveller/nlopt_inverse.h"

namespace millkit::cli {
namespace {

using namespace millkit::leveller;

// Cells keep 15 significant digits (1e-12 mm / 1e-12 deg): enough to carry the 1e-9 mm inverse
// accuracy through a file.
std::string Cell(double value) { return ShortNumber(value, 15); }

LevellerConfig LoadConfig(const std::string& path) {
  return path.empty() ? DefaultLevellerConfig() : LoadLevellerConfig(path);
}

// Header of the input plus the added columns; refuses to overwrite an input column.
std::string HeaderWith(const CsvTable& table, const std::vector<std::string>& added) {
  std::string header;
  for (const auto& c : table.columns) header += (header.empty() ? "" : ",") + c;
  for (const auto& c : added) {
    if (table.HasColumn(c)) {
      throw InputError(table.source + ": column '" + c + "' is an output column; remove it");
    }
    header += "," + c;
  }
  return header + "\n";
}

std::string RowWith(const std::vector<double>& row, const std::vector<double>& added) {
  std::string line;
  for (double v : row) line += (line.empty() ? "" : ",") + Cell(v);
  for (double v : added) line += "," + Cell(v);
  return line + "\n";
}

std::string Where(const CsvTable& table, std::size_t row) {
  return table.source + ":" + std::to_string(table.line_numbers[row]);
}

struct ForwardArgs {
  std::string in, out, geometry;
  bool hydraulic = false;
};

void RunForward(const ForwardArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.in, args.geometry});
  const LevellerConfig config = LoadConfig(args.geometry);
  const Linkage linkage(config.linkage);
  const CsvTable table = ReadCsv(args.in);
  RequireUnits(table, {});
  const int c1 = table.Column(args.hydraulic ? "ah_mm" : "beta1_deg");
  const int c2 = table.Column(args.hydraulic ? "bg_mm" : "beta2_deg");
  std::string text = HeaderWith(table, {"y1_mm", "y2_mm", "y3_mm"});
  const auto& geo = config.linkage;
  const auto& hyd = config.hydraulic;
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    const double u = table.rows[r][c1];
    const double v = table.rows[r][c2];
    Intermesh<double> y;
    bool assembled = false;
    if (args.hydraulic) {
      if (u < hyd.ah_min_mm || u > hyd.ah_max_mm || v < hyd.bg_min_mm || v > hyd.bg_max_mm) {
        throw InputError(Where(table, r) + ": (ah_mm, bg_mm) = (" + FormatNumber(u) + ", " +
                         FormatNumber(v) + ") outside the cylinder ranges [" +
                         FormatNumber(hyd.ah_min_mm) + ", " + FormatNumber(hyd.ah_max_mm) +
                         "] x [" + FormatNumber(hyd.bg_min_mm) + ", " +
                         FormatNumber(hyd.bg_max_mm) + "] mm");
      }
      assembled = linkage.ForwardLengths(u, v, &y);
    } else {
      for (const auto& [name, value] : {std::pair{"beta1_deg", u}, std::pair{"beta2_deg", v}}) {
        if (value < geo.beta_min_deg || value > geo.beta_max_deg) {
          throw InputError(Where(table, r) + ": column '" + name + "' = " + FormatNumber(value) +
                           " outside the working range [" + FormatNumber(geo.beta_min_deg) + ", " +
                           FormatNumber(geo.beta_max_deg) + "] deg");
        }
      }
      assembled = linkage.Forward(u, v, &y);
    }
    if (!assembled) {
      throw InputError(Where(table, r) + ": the linkage does not assemble at this input");
    }
    text += RowWith(table.rows[r], {y.y1, y.y2, y.y3});
  }
  WriteFileAtomically(args.out, text);
}

struct InverseArgs {
  std::string in, out, geometry, method = "nlopt", algorithm = "slsqp";
  double encoder_deg = 0.01;
  double dead_centre_warning_deg = 5.0;
  bool hydraulic = false;
};

NloptInverseOptions InverseOptionsFor(const std::string& name) {
  NloptInverseOptions options;
  if (name == "slsqp") return options;
  options.formulation = InverseFormulation::kLeastSquares;
  if (name == "slsqp-ls")
    options.algorithm = optimize::Algorithm::kLdSlsqp;
  else if (name == "lbfgs")
    options.algorithm = optimize::Algorithm::kLdLbfgs;
  else if (name == "bobyqa")
    options.algorithm = optimize::Algorithm::kLnBobyqa;
  else
    throw InputError("--algorithm must be slsqp, slsqp-ls, lbfgs or bobyqa (got " + name + ")");
  return options;
}

// The nearest reachable pair (by the eccentrics, or by the cylinders when `cylinders` is given),
// rounded to 1e-6 mm inward: moved past the boundary towards the inside (away from the target)
// until the rounded pair itself is reachable, so that typed back as a target it is accepted.
// distance_mm is infinite when no such pair was found.
ReachablePoint NearestInside(const Linkage& linkage, double y1, double y2,
                             const HydraulicRange* cylinders) {
  ReachablePoint nearest = cylinders ? NearestReachableByCylinders(linkage, y1, y2, *cylinders)
                                     : NearestReachable(linkage, y1, y2);
  if (!std::isfinite(nearest.distance_mm)) return nearest;
  const double d1 = nearest.y1_mm - y1;
  const double d2 = nearest.y2_mm - y2;
  const double length = std::hypot(d1, d2);
  for (double step = 1e-6; step <= 1e-2; step *= 10.0) {
    const double u1 = length > 0.0 ? nearest.y1_mm + step * d1 / length : nearest.y1_mm;
    const double u2 = length > 0.0 ? nearest.y2_mm + step * d2 / length : nearest.y2_mm;
    const double r1 = std::round(u1 * 1e6) / 1e6;
    const double r2 = std::round(u2 * 1e6) / 1e6;
    if (cylinders) {
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

void RunInverse(const InverseArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.in, args.geometry});
  if (!(std::isfinite(args.encoder_deg) && args.encoder_deg > 0.0)) {
    throw InputError("--encoder-deg must be > 0 (got " + FormatNumber(args.encoder_deg) + ")");
  }
  if (args.method != "nlopt" && args.method != "closed") {
    throw InputError("--method must be nlopt or closed (got " + args.method + ")");
  }
  const LevellerConfig config = LoadConfig(args.geometry);
  const Linkage linkage(config.linkage);
  const NloptInverse nlopt_inverse(linkage, InverseOptionsFor(args.algorithm));
  const CsvTable table = ReadCsv(args.in);
  RequireUnits(table, {});
  const int c1 = table.Column("y1_mm");
  const int c2 = table.Column("y2_mm");
  const std::vector<std::string> added =
      args.hydraulic ? std::vector<std::string>{"ah_mm", "bg_mm", "y3_mm", "residual_mm"}
                     : std::vector<std::string>{"beta1_deg", "beta2_deg", "y3_mm", "residual_mm",
                                                "accuracy_mm"};
  std::vector<std::string> columns = added;
  for (const char* c : {"nearest_y1_mm", "nearest_y2_mm", "status"}) columns.push_back(c);
  std::string text = HeaderWith(table, columns);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  int not_ok = 0;
  // Every row is written: a target out of reach, or one the solver could not meet, gets its
  // status (and, out of reach, the nearest reachable pair) instead of stopping the batch.
  const auto failed_row = [&](std::size_t r, const std::string& status, double y1, double y2,
                              bool name_nearest, const std::string& why) {
    ++not_ok;
    double n1 = nan, n2 = nan;
    std::string message = Where(table, r) + ": " + status + ": " + why;
    const ReachablePoint nearest =
        name_nearest ? NearestInside(linkage, y1, y2, args.hydraulic ? &config.hydraulic : nullptr)
                     : ReachablePoint{};
    if (name_nearest && !std::isfinite(nearest.distance_mm)) {
      message += "; no reachable pair was found near it";
    } else if (name_nearest) {
      n1 = nearest.y1_mm;
      n2 = nearest.y2_mm;
      char buffer[160];
      if (args.hydraulic) {
        std::snprintf(buffer, sizeof(buffer),
                      "; nearest reachable (y1_mm, y2_mm) = (%.6f, %.6f) at (ah_mm, bg_mm) = "
                      "(%.4f, %.4f)",
                      n1, n2, nearest.ah_mm, nearest.bg_mm);
      } else {
        std::snprintf(buffer, sizeof(buffer),
                      "; nearest reachable (y1_mm, y2_mm) = (%.6f, %.6f) at beta = (%.4f, %.4f) "
                      "deg",
                      n1, n2, nearest.beta1_deg, nearest.beta2_deg);
      }
      message += buffer;
    }
    std::cerr << "millkit: warning: " << message << "\n";
    std::vector<double> cells(added.size(), nan);
    cells.push_back(n1);
    cells.push_back(n2);
    std::string row = RowWith(table.rows[r], cells);
    row.insert(row.size() - 1, "," + status);
    text += row;
  };
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    const double y1 = table.rows[r][c1];
    const double y2 = table.rows[r][c2];
    if (args.hydraulic) {
      const LengthSetpoint lengths = linkage.InverseLengths(y1, y2, config.hydraulic);
      if (!lengths.ok()) {
        failed_row(r, "unreachable", y1, y2, true,
                   "target (" + FormatNumber(y1) + ", " + FormatNumber(y2) +
                       ") is not reachable by the cylinders (" + ToString(lengths.status) + ")");
        continue;
      }
      // A reachable target is its own nearest reachable pair.
      std::string row = RowWith(table.rows[r], {lengths.ah_mm, lengths.bg_mm, lengths.y3_mm,
                                                lengths.residual_mm, y1, y2});
      row.insert(row.size() - 1, ",ok");
      text += row;
      continue;
    }
    const AngleSetpoint closed = linkage.InverseClosedForm(y1, y2);
    if (closed.status != InverseStatus::kOk && closed.status != InverseStatus::kAssemblyMismatch) {
      failed_row(r, "unreachable", y1, y2, true,
                 "target (" + FormatNumber(y1) + ", " + FormatNumber(y2) +
                     ") is outside the linkage's reach (" + ToString(closed.status) + ")");
      continue;
    }
    double beta1 = closed.beta1_deg;
    double beta2 = closed.beta2_deg;
    double y3 = closed.y3_mm;
    double residual = closed.residual_mm;
    if (args.method == "nlopt") {
      const NloptInverseResult solved = nlopt_inverse.Solve(y1, y2);
      if (!solved.summary.accepted) {
        failed_row(r, "not_converged", y1, y2, false, solved.summary.BriefReport());
        continue;
      }
      beta1 = solved.beta1_deg;
      beta2 = solved.beta2_deg;
      y3 = solved.y3_mm;
      residual = solved.summary.residual_mm;
      if (closed.ok() && solved.summary.closed_form_difference_deg > 1e-6) {
        std::cerr << "millkit: warning: " << Where(table, r) << ": NLopt and closed form differ by "
                  << FormatNumber(solved.summary.closed_form_difference_deg)
                  << " deg (both meet the target; the pose is near a dead centre)\n";
      }
    } else if (!closed.ok()) {
      failed_row(r, "not_converged", y1, y2, false, "closed form: " + ToString(closed.status));
      continue;
    }
    const SetpointAccuracy accuracy = linkage.Accuracy(beta1, beta2, args.encoder_deg);
    if (accuracy.dead_centre_distance_deg < args.dead_centre_warning_deg) {
      std::cerr << "millkit: warning: " << Where(table, r) << ": eccentric within "
                << FormatNumber(accuracy.dead_centre_distance_deg)
                << " deg of a dead centre: dY/dbeta is small, the angle is poorly determined\n";
    }
    std::string row =
        RowWith(table.rows[r], {beta1, beta2, y3, residual, accuracy.max_delta_y_mm, y1, y2});
    row.insert(row.size() - 1, ",ok");
    text += row;
  }
  WriteFileAtomically(args.out, text);
  if (not_ok > 0) {
    std::cerr << "millkit leveller inverse: " << not_ok << " of " << table.rows.size()
              << " rows are not ok (status column of " << args.out << ")\n";
    throw NotTrusted("leveller inverse");
  }
}

struct ForcesArgs {
  double yield_mpa = 0.0, width_mm = 0.0, thickness_mm = 0.0, youngs_mpa = 2.1e5;
  std::optional<double> mw_nm;
  double shape_factor = 1.5, original_curvature_per_m = 0.0;
  std::string geometry, out;
};

void RunForces(const ForcesArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.geometry});
  const LevellerConfig config = LoadConfig(args.geometry);
  const std::pair<const char*, double> checks[] = {{"--yield-mpa", args.yield_mpa},
                                                   {"--width-mm", args.width_mm},
                                                   {"--thickness-mm", args.thickness_mm},
                                                   {"--youngs-mpa", args.youngs_mpa}};
  for (const auto& [name, value] : checks) {
    if (!(std::isfinite(value) && value > 0.0)) {
      throw InputError(std::string(name) + " must be > 0 (got " + FormatNumber(value) + ")");
    }
  }
  Strip strip{args.yield_mpa, args.youngs_mpa, args.thickness_mm, args.width_mm};
  ForcesOptions options;
  options.mw_override_Nm = args.mw_nm;
  options.shape_factor = args.shape_factor;
  options.original_curvature_per_m = args.original_curvature_per_m;
  const ForcesReport report = ComputeForces(strip, config.machine, options);

  std::printf("Mw = %.1f N*m%s, Ms = %.1f N*m, kappa_t = %.6f 1/m\n", report.mw_Nm,
              args.mw_nm ? " (given)" : "", report.ms_Nm, report.kappa_t_per_m);
  for (int i = 0; i < 7; ++i) std::printf("P%d = %.3f kN\n", i + 1, report.forces_kN[i]);
  std::printf("sum P = %.3f kN\nMk = %.4f kN*m, friction torque = %.4f kN*m, N = %.2f kW\n",
              report.total_force_kN, report.straightening_torque_kNm, report.friction_torque_kNm,
              report.power_kW);
  for (const auto& w : report.warnings) std::cerr << "millkit: warning: " << w << "\n";
  if (args.out.empty()) return;
  nlohmann::json json;
  json["strip"] = {{"yield_mpa", strip.yield_MPa},
                   {"youngs_mpa", strip.youngs_MPa},
                   {"thickness_mm", strip.thickness_mm},
                   {"width_mm", strip.width_mm}};
  json["mw_Nm"] = report.mw_Nm;
  json["mw_given"] = args.mw_nm.has_value();
  json["ms_Nm"] = report.ms_Nm;
  json["kappa_t_per_m"] = report.kappa_t_per_m;
  json["moments_Nm"] = report.moments_Nm;
  json["forces_kN"] = report.forces_kN;
  json["total_force_kN"] = report.total_force_kN;
  json["straightening_torque_kNm"] = report.straightening_torque_kNm;
  json["friction_torque_kNm"] = report.friction_torque_kNm;
  json["power_kW"] = report.power_kW;
  json["warnings"] = report.warnings;
  json["machine"] = {{"roll_diameter_mm", config.machine.roll_diameter_mm},
                     {"pitch_mm", config.machine.pitch_mm},
                     {"bearing_diameter_mm", config.machine.bearing_diameter_mm},
                     {"rolling_friction_arm_mm", config.machine.rolling_friction_arm_mm},
                     {"bearing_friction", config.machine.bearing_friction},
                     {"speed_m_per_s", config.machine.speed_m_per_s},
                     {"efficiency", config.machine.efficiency}};
  WriteFileAtomically(args.out, json.dump(2) + "\n");
}

struct TableArgs {
  std::string strips, out, geometry;
  double encoder_deg = 0.01;
};

void RunTable(const TableArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.strips, args.geometry});
  const LevellerConfig config = LoadConfig(args.geometry);
  TableOptions options;
  options.encoder_deg = args.encoder_deg;
  options.Validate();
  const CsvTable strips = ReadCsv(args.strips);
  RequireUnits(strips, {});
  const auto cases = ReadStripCases(strips);
  const auto rows = ComputeSetpointTable(cases, config, options);
  int not_ok = 0;
  for (const auto& row : rows) {
    for (const auto& w : row.warnings) {
      std::cerr << "millkit: warning: " << args.strips << ":" << row.input.line << ": " << w
                << "\n";
    }
    if (row.Status() != "ok") ++not_ok;
  }
  WriteFileAtomically(args.out, FormatSetpointTable(rows));
  if (not_ok > 0) {
    std::cerr << "millkit leveller table: " << not_ok << " of " << rows.size()
              << " rows are not ok (status column of " << args.out << ")\n";
    throw NotTrusted("leveller table");
  }
}

}  // namespace

void AddLevellerCommand(CLI::App& app) {
  auto* leveller = app.add_subcommand(
      "leveller", "Seven-roll leveller: linkage kinematics, forces and power, setpoint tables");
  leveller->require_subcommand(1);
  const std::string geometry_help =
      "Leveller TOML ([linkage], [hydraulic], [rolls], [machine]; docs/leveller.md; default: "
      "datasets/leveller/leveller_default.toml)";

  {
    auto args = std::make_shared<ForwardArgs>();
    auto* c = leveller->add_subcommand(
        "forward", "Eccentric angles (beta1_deg, beta2_deg) -> intermesh y1_mm, y2_mm, y3_mm");
    c->add_option("--in", args->in, "CSV with columns beta1_deg,beta2_deg (or ah_mm,bg_mm)")
        ->required();
    c->add_option("--out", args->out, "Output CSV: the input columns + y1_mm,y2_mm,y3_mm")
        ->required();
    c->add_option("--geometry", args->geometry, geometry_help);
    c->add_flag("--hydraulic", args->hydraulic,
                "Hydraulic variant: inputs are the cylinder lengths ah_mm, bg_mm");
    c->callback([args] { RunForward(*args); });
  }
  {
    auto args = std::make_shared<InverseArgs>();
    auto* c = leveller->add_subcommand(
        "inverse", "Intermesh targets (y1_mm, y2_mm) -> eccentric angles, y3, residual, accuracy");
    c->add_option("--in", args->in, "CSV with columns y1_mm,y2_mm")->required();
    c->add_option("--out", args->out,
                  "Output CSV: the input columns + beta1_deg,beta2_deg,y3_mm,residual_mm,"
                  "accuracy_mm (hydraulic: ah_mm,bg_mm,y3_mm,residual_mm)")
        ->required();
    c->add_option("--geometry", args->geometry, geometry_help);
    c->add_option("--encoder-deg", args->encoder_deg,
                  "Eccentric encoder resolution for accuracy_mm (deg)")
        ->capture_default_str();
    c->add_option("--method", args->method,
                  "nlopt (NLopt, cross-checked against the closed form) or closed")
        ->capture_default_str();
    c->add_option("--algorithm", args->algorithm,
                  "NLopt formulation: slsqp (equality-constrained), slsqp-ls, lbfgs, bobyqa "
                  "(least squares)")
        ->capture_default_str();
    c->add_option("--dead-centre-warning-deg", args->dead_centre_warning_deg,
                  "Warn when an eccentric is this close to a dead centre")
        ->capture_default_str();
    c->add_flag("--hydraulic", args->hydraulic,
                "Hydraulic variant: output the cylinder lengths ah_mm, bg_mm");
    c->callback([args] { RunInverse(*args); });
  }
  {
    auto args = std::make_shared<ForcesArgs>();
    auto* c = leveller->add_subcommand(
        "forces", "Roll forces P1..P7, sum, straightening torque and drive power (seed method)");
    c->add_option("--yield-mpa", args->yield_mpa, "Strip yield stress sigma_s (MPa)")->required();
    c->add_option("--width-mm", args->width_mm, "Strip width b (mm)")->required();
    c->add_option("--thickness-mm", args->thickness_mm, "Strip thickness h (mm)")->required();
    c->add_option("--youngs-mpa", args->youngs_mpa, "Young's modulus E (MPa)")
        ->capture_default_str();
    c->add_option("--mw-nm", args->mw_nm,
                  "Elastic-limit moment Mw given explicitly (N*m; the seed's table uses 3460)");
    c->add_option("--shape-factor", args->shape_factor, "Ms/Mw (1.5 for a rectangle)")
        ->capture_default_str();
    c->add_option("--original-curvature-per-m", args->original_curvature_per_m,
                  "Average original strip curvature kappa0 (1/m) in the straightening torque")
        ->capture_default_str();
    c->add_option("--geometry", args->geometry, geometry_help);
    c->add_option("--out", args->out, "JSON report");
    c->callback([args] { RunForces(*args); });
  }
  {
    auto args = std::make_shared<TableArgs>();
    auto* c = leveller->add_subcommand(
        "table", "Setpoint table per strip: intermesh, angles, forces, power, accuracy, warnings");
    c->add_option("--strips", args->strips,
                  "CSV: yield_mpa,thickness_mm,width_mm,entry_plastic_ratio[,youngs_mpa]"
                  "[,exit_curvature_ratio]")
        ->required();
    c->add_option("--out", args->out, "Output table CSV")->required();
    c->add_option("--geometry", args->geometry, geometry_help);
    c->add_option("--encoder-deg", args->encoder_deg, "Eccentric encoder resolution (deg)")
        ->capture_default_str();
    c->callback([args] { RunTable(*args); });
  }
}

}  // namespace millkit::cli
