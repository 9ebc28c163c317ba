#include "millkit/leveller/roll_forces.h"

#include <cmath>
#include <cstdio>

#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::leveller {
namespace {

constexpr double kMmToM = 1e-3;
// A value equal to its limit up to roundoff is not over it (the defaults are the seed's values).
constexpr double kLimitRelativeTolerance = 1e-9;

bool Exceeds(double value, double limit) { return value > limit * (1.0 + kLimitRelativeTolerance); }
constexpr double kMPaToPa = 1e6;

}  // namespace

std::vector<StripDefect> FindStripDefects(const Strip& strip) {
  const std::pair<const char*, double> fields[] = {{"yield_mpa", strip.yield_MPa},
                                                   {"youngs_mpa", strip.youngs_MPa},
                                                   {"thickness_mm", strip.thickness_mm},
                                                   {"width_mm", strip.width_mm}};
  std::vector<StripDefect> defects;
  for (const auto& [name, value] : fields) {
    if (!(std::isfinite(value) && value > 0.0)) {
      defects.push_back({name, "must be > 0 (got " + FormatNumber(value) + ")"});
    }
  }
  return defects;
}

void ValidateStrip(const Strip& strip, const std::string& where) {
  const std::vector<StripDefect> defects = FindStripDefects(strip);
  if (!defects.empty()) {
    throw InputError(where + ": " + defects.front().field + " " + defects.front().rule);
  }
}

double ElasticLimitMoment_Nm(const Strip& strip) {
  const double sigma = strip.yield_MPa * kMPaToPa;
  const double b = strip.width_mm * kMmToM;
  const double h = strip.thickness_mm * kMmToM;
  return sigma * b * h * h / 6.0;
}

double ElasticLimitCurvature_per_m(const Strip& strip) {
  return 2.0 * strip.yield_MPa / (strip.youngs_MPa * strip.thickness_mm * kMmToM);
}

RollMoments SeedMomentProfile(double ms_Nm, double mw_Nm) {
  return {0.0, ms_Nm, ms_Nm, ms_Nm, 0.5 * (ms_Nm + mw_Nm), mw_Nm, 0.0};
}

RollForces RollForcesFromMoments_kN(const RollMoments& m, double pitch_mm) {
  const double t = pitch_mm * kMmToM;
  RollForces p{};
  for (int i = 0; i < 7; ++i) {
    const double left = i > 0 ? m[i - 1] : 0.0;
    const double right = i < 6 ? m[i + 1] : 0.0;
    p[i] = 2.0 * (left + 2.0 * m[i] + right) / t * 1e-3;
  }
  return p;
}

double Sum(const RollForces& forces) {
  double total = 0.0;
  for (double p : forces) total += p;
  return total;
}

double FrictionTorque_kNm(double total_force_kN, const MachineData& machine) {
  const double f = machine.rolling_friction_arm_mm * kMmToM;
  const double d = machine.bearing_diameter_mm * kMmToM;
  return total_force_kN * (f + machine.bearing_friction * d / 2.0);
}

double DrivePower_kW(double straightening_torque_kNm, double total_force_kN,
                     const MachineData& machine) {
  const double D = machine.roll_diameter_mm * kMmToM;
  const double torque = straightening_torque_kNm + FrictionTorque_kNm(total_force_kN, machine);
  return torque * 2.0 * machine.speed_m_per_s / (D * machine.efficiency);
}

double SeedStraighteningTorque_kNm(double ms_Nm, double kappa_t_per_m, double kappa0_per_m,
                                   int roll_count, double roll_diameter_mm) {
  const double D = roll_diameter_mm * kMmToM;
  return ms_Nm * D / 2.0 * (kappa0_per_m + (roll_count - 3) * kappa_t_per_m) * 1e-3;
}

void ForcesOptions::Validate() const {
  if (!(std::isfinite(shape_factor) && shape_factor >= 1.0)) {
    throw InputError::Option("ForcesOptions", "shape_factor",
                             "must be >= 1 (got " + FormatNumber(shape_factor) + ")");
  }
  if (mw_override_Nm && !(std::isfinite(*mw_override_Nm) && *mw_override_Nm > 0.0)) {
    throw InputError::Option("ForcesOptions", "mw_override_Nm",
                             "must be > 0 (got " + FormatNumber(*mw_override_Nm) + ")");
  }
  if (!(std::isfinite(original_curvature_per_m) && original_curvature_per_m >= 0.0)) {
    throw InputError::Option("ForcesOptions", "original_curvature_per_m",
                             "must be >= 0 (got " + FormatNumber(original_curvature_per_m) + ")");
  }
}

std::vector<std::string> CheckMachineLimits(const RollForces& forces_kN, double power_kW,
                                            const MachineData& machine) {
  // snprintf rather than string concatenation: GCC 12 warns falsely (-Wrestrict) on the latter.
  std::vector<std::string> warnings;
  char buffer[160];
  for (int i = 0; i < 7; ++i) {
    if (Exceeds(forces_kN[i], machine.max_roll_force_kN)) {
      std::snprintf(buffer, sizeof(buffer), "P%d = %.1f kN exceeds max_roll_force_kN = %s", i + 1,
                    forces_kN[i], FormatNumber(machine.max_roll_force_kN).c_str());
      warnings.emplace_back(buffer);
    }
  }
  const double total = Sum(forces_kN);
  if (Exceeds(total, machine.max_total_force_kN)) {
    std::snprintf(buffer, sizeof(buffer), "total force %.1f kN exceeds max_total_force_kN = %s",
                  total, FormatNumber(machine.max_total_force_kN).c_str());
    warnings.emplace_back(buffer);
  }
  if (Exceeds(power_kW, machine.motor_power_kW)) {
    std::snprintf(buffer, sizeof(buffer), "power %.1f kW exceeds motor_power_kW = %s", power_kW,
                  FormatNumber(machine.motor_power_kW).c_str());
    warnings.emplace_back(buffer);
  }
  return warnings;
}

ForcesReport ComputeForces(const Strip& strip, const MachineData& machine,
                           const ForcesOptions& options) {
  ValidateStrip(strip, "strip");
  options.Validate();
  ForcesReport report;
  const double mw_stated = ElasticLimitMoment_Nm(strip);
  report.ms_Nm = options.shape_factor * mw_stated;
  report.mw_Nm = options.mw_override_Nm.value_or(mw_stated);
  report.kappa_t_per_m = ElasticLimitCurvature_per_m(strip);
  report.moments_Nm = SeedMomentProfile(report.ms_Nm, report.mw_Nm);
  report.forces_kN = RollForcesFromMoments_kN(report.moments_Nm, machine.pitch_mm);
  report.total_force_kN = Sum(report.forces_kN);
  report.straightening_torque_kNm = SeedStraighteningTorque_kNm(
      report.ms_Nm, report.kappa_t_per_m, options.original_curvature_per_m, machine.roll_count,
      machine.roll_diameter_mm);
  report.friction_torque_kNm = FrictionTorque_kNm(report.total_force_kN, machine);
  report.power_kW = DrivePower_kW(report.straightening_torque_kNm, report.total_force_kN, machine);
  report.warnings = CheckMachineLimits(report.forces_kN, report.power_kW, machine);
  report.mw_given = options.mw_override_Nm.has_value();
  return report;
}

}  // namespace millkit::leveller
