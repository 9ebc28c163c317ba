// The global search of a fit (identify/ internal): a coarse scan, then Levenberg–Marquardt from
// the best distinct scan points, each through a continuation over the window length and directly
// on the whole window. Every local minimum is kept: the verdict compares them.
#pragma once

#include <ceres/ceres.h>

#include <limits>
#include <vector>

#include "identify/fit_model.h"
#include "identify/record_noise.h"
#include "identify/uncertainty.h"
#include "millkit/identify/fit.h"

namespace millkit::identify {

struct LocalFit {
  std::vector<double> u;                                  // scene parameters, unit coordinates
  double cost = std::numeric_limits<double>::infinity();  // projected, whole window
  ceres::Solver::Summary summary;
  bool usable = false;
  bool converged = false;  // Ceres reported CONVERGENCE
  int start = -1;          // which start it came from
  // The inverse covariance JᵀJ / s² at u, in the angles φ (FitModel's ProjectedResidual), when
  // the fit measured it (a final stage); empty otherwise.
  Eigen::MatrixXd precision;
  bool rejoined = false;  // stopped on coming back to a known minimum: it is that minimum
};

// The scan: `start`, then a Latin hypercube of config.scan_points over the scanned slots (the
// others at their start), each point's gains and offsets solved in closed form; its cost is the
// current stage's. Returns up to `count` points, best first, no two closer than
// options.distinct_start (RMS distance in unit coordinates over the scanned slots).
std::vector<std::vector<double>> ScanStarts(const FitModel& model, const FitConfig& config,
                                            const FitOptions& options,
                                            const std::vector<double>& start, int count,
                                            int* evaluated);

// The first continuation stage (the timing parameters on the short window after the onset) from
// every point, cheap because the window is short; returns the `count` best distinct results.
// Many points go in, so that a narrow timing basin (a stiff shaft's small gap) is not left to
// the luck of the scan's ranking.
std::vector<std::vector<double>> PreselectStarts(FitModel* model, const FitOptions& options,
                                                 const std::vector<std::vector<double>>& points,
                                                 int count);

// Levenberg–Marquardt on the current stage of `model` from u; a stage before the last stops at a
// loose tolerance after `iterations` (its answer only has to start the next stage inside the right
// basin). Frozen slots are held. With `known` (a minimum already found, with its precision),
// the fit stops as soon as it comes back to it (FitOptions::rejoin_se) and returns a copy of it.
LocalFit Refine(const FitModel& model, const FitOptions& options, std::vector<double> u,
                bool final_stage, int iterations, const std::vector<int>& frozen = {},
                const LocalFit* known = nullptr);

// The cost (½ χ²) within which a point lies on the minimum's own floor: what the creep stop lets
// 25 more iterations gain (FitOptions::creep_iterations × 1e-3). A probe lower by no more is not a
// lower point (random line 12121: every restart from such a probe creeps and stops as short).
// 0 without the creep stop (creep_iterations or remaining_step_se 0).
double FloorCost(const FitOptions& options);

// The length of u − at.u in the angles φ under at.precision: how many standard errors of the
// linearisation at `at` apart the two points lie, every direction counted (a correlated one
// too). Infinity when `at` has no precision.
double PrecisionLength(const LocalFit& at, const std::vector<double>& u);

// Window divisors of the continuation stages (FitModel::SetStage), the last 1 (whole window).
std::vector<double> ContinuationStages(const FitModel& model, const FitOptions& options);

// Every start refined through the continuation and, besides, directly on the whole window; the
// model is left on the whole window. Returns every local minimum (whole-window costs).
std::vector<LocalFit> RefineStarts(FitModel* model, const FitOptions& options,
                                   const std::vector<std::vector<double>>& starts);

// Everything the global search found.
struct Search {
  std::vector<LocalFit> minima;
  int best = -1;  // the lowest usable minimum; −1 when none is usable
  int starts = 0;
  int scan_points = 0;
  bool escalated = false;
  std::vector<ProfileProbe> probes;       // the axis probes around the best minimum
  std::vector<ProfileProbe> bound_walks;  // held fits inward from a bound (CurvedValleyPoints)
  std::vector<ProfileProbe> gap_points;   // held fits across a gap's range (the same)
};

// The whole search from the start point (unit coordinates). The scan, the preselection, the
// refinement of the starts, the hops and the axis probes each run on options.threads workers
// (MapOverCopies).
//  1. the scan, ranked on the first continuation stage, its best preselect_factor × starts
//     through that stage's fit (PreselectStarts), the best distinct ones refined (RefineStarts);
//  2. when the best minimum fails the misfit test (record noise per block) or no more than half
//     the starts reach it (within χ² 1), once more with escalation_factor × the scan points and
//     twice the starts, from another seed;
//  3. basin hopping from the best minimum (HopPoints), then its gaps kicked (GapKicks), then its
//     sharply curved valleys and bounds walked (CurvedValleyPoints);
//  4. the axis probes (ProfileProbes), restarting from a lower one up to profile_restarts times.
Search GlobalSearch(FitModel* model, const FitConfig& config, const FitOptions& options,
                    const std::vector<ChannelNoise>& noise, const std::vector<double>& start);

// Levenberg–Marquardt on the whole window from u, a point a probe found below the best minimum;
// the fit joins the minima (start −1). When it ends below the best, it becomes the best, the
// axis probes are taken around it, and the function returns true.
bool GoOnBelowBest(FitModel* model, const FitOptions& options, const std::vector<double>& u,
                   Search* search);

}  // namespace millkit::identify
