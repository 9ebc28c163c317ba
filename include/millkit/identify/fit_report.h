// What `millkit identify` writes: the fit as JSON, the fitted trace as CSV, and an SVG of measured
// vs fitted torque and the residual per channel.
#pragma once

#include <string>
#include <vector>

#include "millkit/identify/fit.h"

namespace millkit::identify {

// JSON document: verdict ("ok", "misfit", "ambiguous", "not_converged", "degenerate"; "failed"
// when no fit was made) and warnings (reasons in words), success (verdict ok), scene, records
// (files), parameters (value, standard_error, bounds, start,
// at_bound, identifiable, why_not; record for a per-record copy), channels (record, gain,
// offset with standard errors and at-bound flags, weight, noise measured on the record and its
// source, rms_residual, residual-to-noise variance ratio), correlation
// (names, matrix), not_identifiable (names), multistart (scan points, starts, minima), summary
// (ceres brief report, termination, iterations, simulations, wall time, cost, noise scale).
// A standard error that is not defined (covariance not computable) is null.
std::string FitJson(const FitResult& result, const std::string& scene_file,
                    const std::vector<std::string>& record_files);

// CSV: time, then per channel <column>.measured, <column>.fitted, <column>.residual (N·m). With
// several records a first column `record` (RecordLabels) and the records' rows one after another.
std::string FitTraceCsv(const FitResult& result);

// Notes above the panels: the verdict, every parameter with its standard error (the digits it
// supports) and each channel's gain and offset. Two panels per channel (of each record): the
// measured torque as a thin trace under the fitted line, in N·m, kN·m or MN·m by magnitude; the
// residual in the same unit.
std::string FitPlotSvg(const FitResult& result, const std::string& title);

}  // namespace millkit::identify
