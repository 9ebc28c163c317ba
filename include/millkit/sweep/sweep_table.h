// The outputs of a sweep (issue 5): one CSV row per case, in case order, and plots of Kd
// (SweepPlotPanels).
//
// CSV columns: `case` (0-based), one column per swept parameter (its name), `status` (ok |
// failed), `events`, then per reported link `kd.<link>` and `peak_Nm.<link>`, and `message` last
// (double-quoted; why the case failed, empty otherwise). Numbers are the shortest text that reads
// back to the same double. Empty cells: Kd undefined (static torque 0), or a failed case.
#pragma once

#include <string>
#include <vector>

#include "millkit/io/svg_plot.h"
#include "millkit/sweep/sweep_case.h"
#include "millkit/sweep/sweep_config.h"

namespace millkit::sweep {

std::string FormatSweepCsv(const driveline::Scene& scene, const SweepConfig& config,
                           const CaseList& cases, const std::vector<CaseResult>& results);

// Plots of Kd. A grid over two parameters: one heat map per reported link (the first parameter
// across, the second up), all links on one colour scale, failed cases and undefined Kd grey. A
// grid over one parameter: a line with markers per link against it. Otherwise (Latin hypercube,
// grids over three or more parameters): one panel per parameter, each link's Kd of every case
// against it (markers).
std::vector<PlotPanel> SweepPlotPanels(const driveline::Scene& scene, const SweepConfig& config,
                                       const CaseList& cases,
                                       const std::vector<CaseResult>& results);

// A CSV cell: the text double-quoted, inner quotes doubled, line breaks as spaces.
std::string QuotedCell(const std::string& text);

}  // namespace millkit::sweep
