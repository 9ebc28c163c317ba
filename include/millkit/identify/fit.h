// Identification of drive-line parameters from oscillograms (SPEC.md §4; issues 3 and 12).
//
// The model of channel c at record time t_k is  y_ck ≈ g_c · m_c(t_k; p) + o_c, with m_c the
// simulated torque of the channel's link (exact solver, sampled at the record's own times: the
// model is resampled, never the data), p the free scene parameters (damping, backlash, stiffness,
// inertia, gap_position, bite_time, ...), g_c and o_c the channel's gain and offset, bounded
// (gain 0.5–2, offset within ± the channel's peak unless the config says otherwise). The fit
// minimises ½ Σ_c Σ_k w_c² (g_c m_ck + o_c − y_ck)² over the window, with w_c = 1/σ_c fixed
// before any model is run: σ_c is the channel's noise measured on the record itself
// (identify/record_noise.h). Every candidate minimum is compared on that one cost.
//
// Several records: each is its own run of the scene; scene parameters are shared, a per-record
// parameter (bite_time by default) has one value per record, every channel of every record its
// own gain and offset.
//
// The search (identify/multistart.h, GlobalSearch): a Latin-hypercube scan over every free
// parameter marked `scan` (all by default; dampings and stiffnesses on a log scale,
// identify/parameter_map.h), ranked on a short window after the onset with gains and offsets
// solved in closed form at each point (variable projection); the timing of the best points fitted
// on that window; Levenberg–Marquardt from the best distinct ones through a fine continuation
// over the window length and directly on the whole window; one escalated search when the best
// minimum misfits; basin hops and axis probes around the best. Derivatives, while iterating and
// for the covariance: the exact solver's forward sensitivities through the events, or finite
// differences (FitOptions::derivatives).
//
// Uncertainty: the covariance of every fitted quantity from the noise-weighted Jacobian,
// scaled by the residual variance 2·cost/(N − P) (the report says so); where the cost along a
// parameter's profile direction rises slower than the linearisation says, its standard error is
// widened to match. Parameters the record cannot determine are flagged not identifiable.
//
// The verdict (FitSummary::verdict), in this order:
//   degenerate     the record cannot support the fit (a value that is not a torque, a flat or
//                  dead channel, fewer samples after the response starts than fitted quantities);
//   not_converged  Levenberg–Marquardt did not converge at the best minimum (and, after the
//                  rules below, when a probe beside the answer found a lower cost, or when only
//                  a basin hop or an axis probe reached the best minimum, at a χ² more than
//                  ambiguity_chi2 below every start's and no start's fit within
//                  distinct_minimum_se of it under its linearisation: the starts missed its
//                  valley, and may have missed a lower one; a start's fit that close stopped
//                  on the valley's rough floor, which only a warning reports);
//   misfit         some channel's residual is not its noise, at the one-sided level misfit_z:
//                  its variance exceeds the noise variance (log-ratio test, both variances'
//                  degrees of freedom), or its autocorrelation over up to 20 lags differs from
//                  the quiet stretch's (portmanteau test, Wilson–Hilferty normal z);
//   ambiguous      another local minimum, more than distinct_minimum_se standard errors away in
//                  some identifiable parameter, has a χ² within ambiguity_chi2 of the best;
//   ok             otherwise (parameters flagged not identifiable are still ok).
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/driveline/sensitivity.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"

namespace millkit::identify {

// A channel's recorder low-pass runs inside the model (driveline::Link::recorder_lowpass_Hz),
// exact at the record's times at any cutoff. Where two channels of one link have different
// filters the model is sampled at kFilterOversample points per record step from the record's
// start and each channel's filter applied as linear between them.
inline constexpr int kFilterOversample = 16;

// Every knob of the fit's strategy and judgement. The defaults are set by the random-lines
// benchmark (bench/identify/bench_random_lines.cpp), not by any one scene.
struct FitOptions {
  // Levenberg–Marquardt at the final stage.
  int max_iterations = 100;
  double function_tolerance = 1e-9;
  double parameter_tolerance = 1e-8;
  // ... or once the Gauss–Newton step still to go from the current point is shorter than
  // remaining_step_se standard errors (its length under the covariance s² (JᵀJ)⁻¹, s² the
  // residual variance left after that step), or shorter than rough_step_se after a step that
  // changed the cost by less than 1e-3 (½ χ²). The misfit of a record with impacts is rough on
  // the scale of 0.05–0.2 standard errors (the event sequence changes): iterating closer costs
  // rejected steps and moves no estimate by a visible fraction of its standard error.
  // remaining_step_se = 0 turns both tests off.
  double remaining_step_se = 0.02;
  double rough_step_se = 0.1;
  // ... or once the cost has fallen by no more than creep_iterations × 1e-3 (½ χ²) over the last
  // creep_iterations iterations: Levenberg–Marquardt creeps along a floor the Gauss–Newton step
  // overrates (random line 12024: 300 more iterations moved no estimate by 0.01 of its standard
  // error and lowered χ² by 0.03). With remaining_step_se; 0: not tested.
  int creep_iterations = 25;
  double derivative_step = 1e-6;  // in unit coordinates (fraction of the bound range)
  // How the fit differentiates the model, while iterating and for the covariance: the exact
  // solver's forward sensitivities (the default; at a point where they are not available, a
  // grazing event or a degenerate switch, that one Jacobian falls back to forward differences
  // while iterating and to central differences for the covariance), forward differences in the
  // unit coordinates with derivative_step, or central differences. The sensitivities are about
  // 1000 times more accurate than forward differences, and one run with them costs about 6
  // plain runs against the P + 1 of forward differences (bench_sensitivity, README.md).
  // Forward and central differences take central differences for the covariance.
  Derivatives derivatives = Derivatives::kSensitivity;
  // Worker threads of the search: the scan, the preselection, the starts, the hops and the axis
  // probes run on this many threads. Every result is the same for any count.
  int threads = 1;

  // Continuation: stages end at onset + span/d, d = first_stage_divisor, then divided by
  // continuation_ratio down to 1; the first timing_only_stages fit only gaps, gap positions and
  // the bite time; a stage before the last stops after stage_iterations. A stiff shaft with a
  // small gap rattles many times over a record: its cost valley in the gap narrows as the window
  // grows, and a stage that grows the window too much at once jumps out of it.
  double first_stage_divisor = 16.0;
  double continuation_ratio = 1.189207115002721;
  int timing_only_stages = 1;
  int stage_iterations = 10;
  // The starts go through the stages side by side; a start that ends a stage before the last
  // within merge_distance of an earlier start's end, in every unit coordinate (each parameter's
  // place between its bounds, on its log scale where it has one), would follow the same path:
  // it stops there and takes that start's continued fit. 0 turns it off.
  double merge_distance = 1e-6;
  // The direct whole-window fit of a start is finished only when its try, capped at
  // direct_try_iterations, ends below direct_retry_factor times the continued fit's cost.
  double direct_retry_factor = 1.5;
  int direct_try_iterations = 10;
  // When the best minimum fails the misfit test, one more search with escalation_factor times the
  // scan points (other points) and twice the starts; 1: none.
  int escalation_factor = 4;
  // The scan's best preselect_factor × starts points go through the first continuation stage
  // (cheap: a short window); the best distinct results are the starts.
  int preselect_factor = 4;
  // Scan points closer than this (RMS over the scanned unit coordinates) are one start.
  double distinct_start = 0.1;

  // Identifiability: a parameter is flagged when the column-scaled Jacobian is rank-deficient
  // in its direction (reciprocal condition below rank_tolerance) or its standard error exceeds
  // unidentifiable_fraction of its bound range on the scale it is fitted on (a log scale for a
  // damping, stiffness or inertia whose bounds span a factor of 4 or more).
  double rank_tolerance = 1e-7;
  double unidentifiable_fraction = 0.25;
  // The profile check of the standard errors probes ± profile_step standard errors, and each
  // parameter's axis at profile_points points; an axis probe within profile_chi2 of the best χ²
  // widens the standard error (identify/uncertainty.h). A probe below the best cost restarts
  // Levenberg–Marquardt from it, up to profile_restarts times in the search (the axis probes)
  // and as many again in the standard errors' check (its profile probes and held points).
  double profile_step = 2.0;
  int profile_points = 8;
  double profile_chi2 = 25.0;
  int profile_restarts = 2;
  // The profile probes are relaxed: one Gauss–Newton step of the other quantities from each
  // (the Jacobian at the minimum), since the valley may curve away from the straight profile
  // direction. Where a relaxed probe implies a standard error more than profile_relax_widening
  // times the linearised one, or the straight probe rises more than profile_bend_ratio times
  // the prediction, or the relaxed probe at 2 × profile_step implies more than
  // profile_relax_widening times (a profile that flattens beyond the step), that side of the
  // profile is followed: Levenberg–Marquardt with the parameter held (profile_iterations each)
  // at profile_step × 1, 2, 4, … up to profile_relax_reach standard errors, until χ² passes
  // profile_chi2 or a bound; each point held at χ² widens every parameter it moved by d to
  // d / √max(χ², 1). 0: no relaxing.
  double profile_relax_widening = 1.15;
  double profile_bend_ratio = 10.0;
  int profile_iterations = 3;
  double profile_relax_reach = 16.0;
  // After the basin hops, a parameter whose straight probes rise more than curved_valley_ratio
  // times the prediction has its profile followed from the best minimum (identify/uncertainty.h,
  // CurvedValleyPoints; curved_valley_iterations each); so has, inward, a parameter at one of
  // its bounds, and each point held there widens every standard error it implies (a point at χ²
  // moved by d: d / √max(χ², 1)). A lower point found is refined, and the best minimum it
  // reaches counts as one no start reached. 0: neither is followed.
  double curved_valley_ratio = 100.0;
  int curved_valley_iterations = 20;
  // With the curved valleys: a parameter within bound_walk_se standard errors of a bound (in unit
  // coordinates) is walked inward from it as one at the bound is: its interval reaches past the
  // bound, and the fit may have stopped short of it. 0: only a parameter at its bound.
  double bound_walk_se = 2.0;
  // With the curved valleys: a gap that never closes at the best minimum (its backlash fails the
  // identifiability test above and the cost is the same at every larger gap) may sit where
  // another parameter makes up for it, while the truth's valley, where the gap closes briefly,
  // is a narrow one just below the smallest gap that stays open. That edge is found by bisection
  // (the others held), and the gap held at edge × (1 − 2⁻ᵏ), k = open_gap_points … 1 (in unit
  // coordinates), the others refitted; a lower point found is refined as above. 0: none.
  int open_gap_points = 6;
  // With the curved valleys: every fitted backlash held at gap_profile_points points evenly
  // across its range ((k + ½)/points in unit coordinates; none within profile_step standard
  // errors of the best minimum), the others refitted (profile_iterations each). A gap's profile
  // can have a second valley behind a wall that the probes near the minimum never cross: a held
  // point within profile_chi2 that moved a parameter by d widens its error to d / √max(χ², 1),
  // the gap's and the others' (nothing carried over by their correlations at the minimum, which
  // say nothing that far away), and a lower one is refined. 0: none.
  int gap_profile_points = 8;
  // Basin hopping from the best minimum: hops refinements from points hop_radius standard
  // errors away in random directions (seeded by hop_seed); a lower one becomes the best.
  int hops = 4;
  double hop_radius = 5.0;
  unsigned hop_seed = 1;
  // Gap kicks, after the hops: each fitted backlash set gap_kick × 2ᵏ wider and narrower
  // (relative; k = 0 … gap_kick_levels − 1: 2 % and 4 %) from the best minimum and refined with
  // everything free. A wide gap's impact timing makes its misfit a row of narrow valleys a few
  // per cent of the gap apart, which the hops' random directions rarely hit and a point held in
  // the next one does not show (it costs more than the minimum until released); the next valley
  // may lie one or two of them away (random line 1439: 2 %; 8395: 4 %). 0: none.
  double gap_kick = 0.02;
  int gap_kick_levels = 2;
  // A fit that may only come back to a minimum already found (a basin hop to the best minimum,
  // a start's direct fit to its continued one) stops at the first iterate within rejoin_se of
  // it: the Mahalanobis length of the difference under that minimum's covariance, which bounds
  // every parameter's difference in standard errors, at a χ² not lower by more than 1. It is
  // then that minimum (its values, cost and convergence). 0 turns the test off.
  double rejoin_se = 0.5;

  // Verdict levels (see above).
  double misfit_z = 3.0;
  double ambiguity_chi2 = 4.0;
  double distinct_minimum_se = 3.0;

  // Called after every simulation with what the fit is doing and the simulations so far (the
  // command line throttles it into a progress line); none when empty.
  std::function<void(const std::string& activity, long simulations)> progress;

  // Throws InputError naming the option and its rule.
  void Validate() const;
};

struct ParameterEstimate {
  std::string name;    // scene parameter name; name@<record label> for a per-record copy
  std::string record;  // source of the record a per-record copy belongs to (else empty)
  std::string unit;
  double value = 0.0;
  double standard_error = 0.0;
  double start = 0.0;
  double lower = 0.0;
  double upper = 0.0;
  bool at_bound = false;
  bool identifiable = true;
  std::string why_not;  // when not identifiable
};

// One channel of one record. Torques (offset, noise, residual, traces) are in the channel's unit.
struct ChannelEstimate {
  std::string column;
  std::string link;
  std::string record;        // the record's source (file)
  std::string record_label;  // RecordLabels() of the fit's records
  std::string unit = "N*m";  // ChannelSpec::unit
  double gain = 1.0;
  double gain_se = 0.0;
  double offset = 0.0;
  double offset_se = 0.0;
  double weight = 0.0;       // 1/unit, as used in the fit
  double noise = 0.0;        // the channel's noise measured on the record
  std::string noise_source;  // "quiet stretch (m samples)" or "second differences"
  double chi2_ratio = 0.0;   // residual variance / noise variance
  double whiteness_z = 0.0;  // the residual's autocorrelation against the noise's, as a normal z
  bool gain_at_bound = false;
  bool offset_at_bound = false;
  double rms_residual = 0.0;
  int samples = 0;
  std::vector<double> time_s;  // the window samples' times (s)
  std::vector<double> fitted;  // g·m + o at the window samples
  std::vector<double> measured;
};

struct LocalMinimum {
  double cost = 0.0;  // the fixed-weight cost: every minimum on the same scale
  int start = 0;
  std::vector<double> values;  // free scene parameters, physical units
  int iterations = 0;
  bool converged = false;
};

struct FitSummary {
  bool success = false;
  // "ok", "misfit", "ambiguous", "not_converged" or "degenerate" (empty when the fit failed).
  std::string verdict;
  std::vector<std::string> warnings;  // reasons for the verdict and other doubts, in words
  std::string message;
  std::string ceres_brief;  // ceres::Solver::Summary::BriefReport() of the final fit
  std::string termination;
  int iterations = 0;
  int scan_points = 0;
  int starts = 0;
  bool escalated = false;  // the misfit of the first search's best minimum asked for a second
  int starts_at_best = 0;  // starts whose fits reach the best minimum (same point)
  long simulations = 0;
  double wall_time_s = 0.0;
  double cost = 0.0;  // ½ Σ weighted residual²
  int residuals = 0;
  int fitted_quantities = 0;
  double noise_scale = 1.0;  // sqrt(2 cost / (N − P)); ≈ 1 when the noise estimates are right
  double reciprocal_condition = 0.0;  // of the column-scaled Jacobian
  std::string BriefReport() const;
};

struct FitResult {
  std::vector<ParameterEstimate> parameters;
  std::vector<ChannelEstimate> channels;  // record by record, channels in config order
  // Parameters, then gain.<col>, offset.<col> (with @<record label> when there are several).
  std::vector<std::string> quantity_names;
  Eigen::MatrixXd correlation;  // over quantity_names
  std::vector<LocalMinimum> minima;
  // Per record: the record time (s) that is the model's t = 0 (TimeOrigin). The window, traces and
  // plots are in record time; bite_time and the scene's torque times count from the origin.
  std::vector<double> time_origins_s;
  FitSummary summary;
};

// Fits `config` to the records starting from `scene` (with [set] values already applied). Each
// record is a separate run of the scene (another bite of the same line): the scene parameters
// are shared, a per-record parameter (bite_time by default) and every channel's gain and offset
// are fitted per record. Throws InputError for bad options; a fit that fails (every start fails
// to simulate, Ceres reports failure) has summary.success = false and a message.
FitResult Fit(const driveline::Scene& scene, const std::vector<Oscillogram>& records,
              const FitConfig& config, const FitOptions& options);
FitResult Fit(const driveline::Scene& scene, const Oscillogram& record, const FitConfig& config,
              const FitOptions& options);

// Cramér–Rao bound of the free scene parameters (physical units, in config order) for a record
// with white noise of the given standard deviation per channel (N·m), at the values in `scene`
// (gains 1, offsets 0): sqrt(diag((JᵀJ)⁻¹)) with the noise-weighted central-difference Jacobian
// over the scene parameters, gains and offsets. NaN when J is rank-deficient. Throws
// InputError when the scene does not simulate.
std::vector<double> CramerRaoBound(const driveline::Scene& scene, const Oscillogram& record,
                                   const FitConfig& config, const std::vector<double>& noise_Nm,
                                   const FitOptions& options);

// The record time that is the model's time zero: [fit] time_origin, else the record's first
// sample (a logger's absolute time fits like a record that starts at 0).
double TimeOrigin(const FitConfig& config, const Oscillogram& record);

// Simulated torque of each channel's link at the record times in [begin, end), the model's time
// being record time − origin_s; the scene's parameters as given. Returns false with a reason when
// the scene is invalid or the solver fails. With `kept`, the exact solver's run is kept there for
// ChannelDerivatives.
bool SimulateChannels(const driveline::Scene& scene, const Oscillogram& record, double origin_s,
                      const std::vector<ChannelSpec>& channels, int begin, int end,
                      std::vector<Eigen::VectorXd>* torques, std::string* why,
                      driveline::RecordedRun* kept = nullptr);
// The same with each channel's derivatives over `parameters` (derivatives[c]: samples ×
// parameters), by the exact solver's forward sensitivities (millkit/driveline/sensitivity.h).
// When they cannot be computed (a grazing event, a degenerate switch) the torques are still
// returned, `unavailable` says why and `derivatives` is left as it was.
bool SimulateChannels(const driveline::Scene& scene, const Oscillogram& record, double origin_s,
                      const std::vector<ChannelSpec>& channels, int begin, int end,
                      std::vector<Eigen::VectorXd>* torques, std::string* why,
                      const std::vector<driveline::SceneParameter>& parameters,
                      std::vector<Eigen::MatrixXd>* derivatives, std::string* unavailable);
// The derivatives the call above gives, along a run `kept` by the first SimulateChannels with the
// same record, origin_s, channels, begin and end, without running the solver again (the torques
// are that call's). False with a reason when the kept run failed; std::logic_error for a run that
// is empty or of another window.
bool ChannelDerivatives(const driveline::RecordedRun& kept, const Oscillogram& record,
                        double origin_s, const std::vector<ChannelSpec>& channels, int begin,
                        int end, const std::vector<driveline::SceneParameter>& parameters,
                        std::vector<Eigen::MatrixXd>* derivatives, std::string* unavailable,
                        std::string* why);

}  // namespace millkit::identify
