// What `millkit leveller forces` writes (docs/leveller.md): the summary printed on the terminal
// and the JSON report, both from ComputeForces (roll_forces.h).
#pragma once

#include <string>

#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/roll_forces.h"

namespace millkit::leveller {

// Lines "Mw = ... N*m[ (given)], Ms = ..., kappa_t = ...", "P1 = ... kN" ... "P7", "sum P = ...",
// "Mk = ..., friction torque = ..., N = ... kW" (the warnings are not part of it).
std::string FormatForcesSummary(const ForcesReport& report);

// JSON text (2-space indent, ending in a newline): "strip" (yield_mpa, youngs_mpa, thickness_mm,
// width_mm), the report's values (mw_Nm, mw_given, ms_Nm, kappa_t_per_m, moments_Nm, forces_kN,
// total_force_kN, straightening_torque_kNm, friction_torque_kNm, power_kW, warnings) and
// "machine" (the MachineData the forces were computed for, without the limits).
std::string ForcesReportJson(const Strip& strip, const MachineData& machine,
                             const ForcesReport& report);

}  // namespace millkit::leveller
