// What `millkit coupling` writes (issue 5): the answer as JSON, a table for the terminal, and the
// Kd-vs-variable curve as CSV and plot panels.
//
// Curve CSV columns: `variable` (the one that moves; the others stay at the answer), `value`,
// `status` (ok | failed), `feasible` (1 when every limit holds), `lowest_frequency_Hz`, one
// `twist_rad.<link>` per twist limit, `kd_max` (over the counted links), `kd.<link>` per counted
// link, `message` (quoted). Empty numeric cells for a failed simulation.
#pragma once

#include <string>
#include <vector>

#include "millkit/io/svg_plot.h"
#include "millkit/optimize/coupling/coupling_optimizer.h"

namespace millkit::coupling {

std::string CouplingResultJson(const driveline::Scene& scene, const CouplingProblem& problem,
                               const CouplingResult& result);

std::string FormatCouplingTable(const driveline::Scene& scene, const CouplingProblem& problem,
                                const CouplingResult& result);

std::string FormatCurveCsv(const driveline::Scene& scene, const CouplingProblem& problem,
                           const std::vector<CurvePoint>& curve);

// One panel per variable: Kd_max (a wide light band when several links are counted), Kd of each
// counted link (lines of distinct dashes), points that break a limit (hollow markers) and the
// answer (a filled marker drawn last).
std::vector<PlotPanel> CurvePlotPanels(const driveline::Scene& scene,
                                       const CouplingProblem& problem,
                                       const std::vector<CurvePoint>& curve,
                                       const CouplingPoint& answer);

}  // namespace millkit::coupling
