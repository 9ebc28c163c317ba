#include "millkit/leveller/forces_report.h"

#include <cstdio>
#include <nlohmann/json.hpp>

namespace millkit::leveller {

std::string FormatForcesSummary(const ForcesReport& report) {
  std::string text;
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer), "Mw = %.1f N*m%s, Ms = %.1f N*m, kappa_t = %.6f 1/m\n",
                report.mw_Nm, report.mw_given ? " (given)" : "", report.ms_Nm,
                report.kappa_t_per_m);
  text += buffer;
  for (int i = 0; i < 7; ++i) {
    std::snprintf(buffer, sizeof(buffer), "P%d = %.3f kN\n", i + 1, report.forces_kN[i]);
    text += buffer;
  }
  std::snprintf(buffer, sizeof(buffer),
                "sum P = %.3f kN\nMk = %.4f kN*m, friction torque = %.4f kN*m, N = %.2f kW\n",
                report.total_force_kN, report.straightening_torque_kNm, report.friction_torque_kNm,
                report.power_kW);
  text += buffer;
  return text;
}

std::string ForcesReportJson(const Strip& strip, const MachineData& machine,
                             const ForcesReport& report) {
  nlohmann::json json;
  json["strip"] = {{"yield_mpa", strip.yield_MPa},
                   {"youngs_mpa", strip.youngs_MPa},
                   {"thickness_mm", strip.thickness_mm},
                   {"width_mm", strip.width_mm}};
  json["mw_Nm"] = report.mw_Nm;
  json["mw_given"] = report.mw_given;
  json["ms_Nm"] = report.ms_Nm;
  json["kappa_t_per_m"] = report.kappa_t_per_m;
  json["moments_Nm"] = report.moments_Nm;
  json["forces_kN"] = report.forces_kN;
  json["total_force_kN"] = report.total_force_kN;
  json["straightening_torque_kNm"] = report.straightening_torque_kNm;
  json["friction_torque_kNm"] = report.friction_torque_kNm;
  json["power_kW"] = report.power_kW;
  json["warnings"] = report.warnings;
  json["machine"] = {{"roll_diameter_mm", machine.roll_diameter_mm},
                     {"pitch_mm", machine.pitch_mm},
                     {"bearing_diameter_mm", machine.bearing_diameter_mm},
                     {"rolling_friction_arm_mm", machine.rolling_friction_arm_mm},
                     {"bearing_friction", machine.bearing_friction},
                     {"speed_m_per_s", machine.speed_m_per_s},
                     {"efficiency", machine.efficiency}};
  return json.dump(2) + "\n";
}

}  // namespace millkit::leveller
