// What `millkit identify` writes: the fit as JSON, the fitted trace as CSV, and an SVG of measured
// vs fitted torque and the residual per channel.
#pragma once

#include <string>

#include "identify/fit.h"

namespace millkit::identify {

// JSON document: parameters (value, standard_error, bounds, start, at_bound, identifiable,
// why_not), channels (gain, offset with standard errors, weight, rms_residual), correlation
// (names, matrix), not_identifiable (names), multistart (scan points, starts, minima), summary
// (ceres brief report, termination, iterations, simulations, wall time, cost, noise scale).
// A standard error that is not defined (covariance not computable) is null.
std::string FitJson(const FitResult& result, const std::string& scene_file,
                    const std::string& record_file);

// CSV: time, then per channel <column>.measured, <column>.fitted, <column>.residual (N·m).
std::string FitTraceCsv(const FitResult& result);

// Two panels per channel: measured and fitted torque; residual.
std::string FitPlotSvg(const FitResult& result, const std::string& title);

}  // namespace millkit::identify
