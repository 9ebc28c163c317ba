// `millkit leveller forward|inverse|forces|table` (issue 4, SPEC.md §6, §8). Parses the flags,
// calls the leveller library (the NLopt inverse through optimize/leveller), prints its warnings and
// writes its outputs atomically. No physics and no result formatting here.
#include <cmath>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/csv.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"
#include "millkit/io/output_files.h"
#include "millkit/leveller/forces_report.h"
#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/linkage_table.h"
#include "millkit/leveller/roll_forces.h"
#include "millkit/leveller/setpoint_table.h"
#include "millkit/optimize/leveller/inverse_table.h"

namespace millkit::cli {
namespace {

using namespace millkit::leveller;

LevellerConfig LoadConfig(const std::string& path) {
  return path.empty() ? DefaultLevellerConfig() : LoadLevellerConfig(path);
}

LinkageDrive DriveFor(bool hydraulic) {
  return hydraulic ? LinkageDrive::kHydraulic : LinkageDrive::kEccentric;
}

struct ForwardArgs {
  std::string in, out, geometry;
  bool hydraulic = false;
};

void RunForward(const ForwardArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.in, args.geometry});
  const LevellerConfig config = LoadConfig(args.geometry);
  const CsvTable table = ReadCsv(args.in);
  RequireUnits(table, {});
  const ForwardTable result = ComputeForwardTable(table, config, DriveFor(args.hydraulic));
  WriteFileAtomically(args.out, FormatForwardTable(result));
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

void RunInverse(const InverseArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.in, args.geometry});
  if (!(std::isfinite(args.encoder_deg) && args.encoder_deg > 0.0)) {
    throw InputError("--encoder-deg must be > 0 (got " + FormatNumber(args.encoder_deg) + ")");
  }
  if (args.method != "nlopt" && args.method != "closed") {
    throw InputError("--method must be nlopt or closed (got " + args.method + ")");
  }
  const LevellerConfig config = LoadConfig(args.geometry);
  InverseTableOptions options;
  options.drive = DriveFor(args.hydraulic);
  options.method = args.method == "closed" ? InverseMethod::kClosedForm : InverseMethod::kNlopt;
  options.nlopt = InverseOptionsFor(args.algorithm);
  options.encoder_deg = args.encoder_deg;
  options.dead_centre_warning_deg = args.dead_centre_warning_deg;
  const CsvTable table = ReadCsv(args.in);
  RequireUnits(table, {});
  const InverseTable result = ComputeInverseTable(table, config, options);
  for (std::size_t r = 0; r < result.rows.size(); ++r) {
    for (const auto& w : result.rows[r].warnings) {
      std::cerr << "millkit: warning: " << RowLocation(table, r) << ": " << w << "\n";
    }
  }
  WriteFileAtomically(args.out, FormatInverseTable(result));
  if (const int not_ok = result.NotOkCount(); not_ok > 0) {
    std::cerr << "millkit leveller inverse: " << not_ok << " of " << result.rows.size()
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

// The flag that sets each Strip field, in the order the flags are reported.
constexpr std::pair<const char*, const char*> kStripFlags[] = {{"--yield-mpa", "yield_mpa"},
                                                               {"--width-mm", "width_mm"},
                                                               {"--thickness-mm", "thickness_mm"},
                                                               {"--youngs-mpa", "youngs_mpa"}};

void RunForces(const ForcesArgs& args) {
  CheckOutputPaths({{"--out", args.out}}, {args.geometry});
  const LevellerConfig config = LoadConfig(args.geometry);
  const Strip strip{args.yield_mpa, args.youngs_mpa, args.thickness_mm, args.width_mm};
  const std::vector<StripDefect> defects = FindStripDefects(strip);
  for (const auto& [flag, field] : kStripFlags) {
    for (const auto& defect : defects) {
      if (defect.field == field) throw InputError(std::string(flag) + " " + defect.rule);
    }
  }
  ForcesOptions options;
  options.mw_override_Nm = args.mw_nm;
  options.shape_factor = args.shape_factor;
  options.original_curvature_per_m = args.original_curvature_per_m;
  const ForcesReport report = ComputeForces(strip, config.machine, options);
  std::cout << FormatForcesSummary(report);
  for (const auto& w : report.warnings) std::cerr << "millkit: warning: " << w << "\n";
  if (args.out.empty()) return;
  WriteFileAtomically(args.out, ForcesReportJson(strip, config.machine, report));
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
