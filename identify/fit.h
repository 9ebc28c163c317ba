// Identification of drive-line parameters from oscillograms (SPEC.md §4, issue 3).
//
// The model of channel c at record time t_k is  y_ck ≈ g_c · m_c(t_k; p) + o_c, with m_c the
// simulated torque of the channel's link (exact solver, sampled at the record's own times: the
// model is resampled, never the data), p the free scene parameters (damping, backlash, stiffness,
// inertia, gap_position, bite_time, ...), g_c and o_c the channel's gain and offset. Ceres
// minimises Σ_c Σ_k w_c² (g_c m_ck + o_c − y_ck)² over the window.
//
// Derivatives: ∂m/∂p by finite differences on the exact solver, forward while iterating (by
// default) and central for the covariance (normalised step 1e-6 of the
// bound width; the solver's ~1e-12 relative roundoff makes the derivative error ~1e-6 relative,
// the truncation error ~1e-12), second-order one-sided at a bound; gain and offset analytic.
// Backlash moves impact times, but with the `limited` law the sampled torque is continuous in p,
// so the differences are smooth except where an event crosses a sample time.
//
// Several records: each is its own run of the scene; scene parameters are shared, a per-record
// parameter (bite_time by default) has one value per record, every channel of every record its
// own gain and offset. The residual is all records' channels, one after another.
//
// Non-convexity: a continuation over the window length (the first stage ends shortly after the
// response starts, each next stage doubles the span; the first kTimingOnlyStages fit only the
// scanned parameters), a coarse Latin-hypercube scan over the parameters marked `scan` (gaps,
// bite time) on the first stage, with gains and offsets solved linearly at each point, then Ceres
// (Levenberg–Marquardt) through the stages from the best `starts` points. Each start is also
// fitted on the whole window directly (a short stage can carry the dampings into a neighbouring
// basin that a good start never leaves); the best minimum wins, and every minimum is reported.
// Weights: a channel without a weight is first weighted by 1/peak, then by 1/noise estimated from
// its residual, and the fit is polished with those weights.
//
// Uncertainty: ceres::Covariance (dense SVD) of all fitted quantities, scaled by the residual
// variance 2·cost/(N − P) (≈ 1 with noise weights). A parameter is flagged not identifiable when
// the column-scaled Jacobian is rank-deficient in its direction (reciprocal condition below
// kRankTolerance) or its standard error exceeds kUnidentifiableFraction of its bound width; its
// value and standard error are then not to be trusted and the JSON says so.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Dense>

#include "driveline/scene.h"
#include "identify/fit_config.h"
#include "identify/oscillogram.h"

namespace millkit::identify {

inline constexpr double kRankTolerance = 1e-7;
inline constexpr double kUnidentifiableFraction = 0.25;
// Window-length continuation: stages end at onset + span/2^j, j = kContinuationStages − 1 … 0.
inline constexpr int kContinuationStages = 5;
// The first stage fits only the scanned parameters (gaps, bite time) and the nuisance gains and
// offsets; the rest (dampings, stiffness) join afterwards. Measured on the bundled fit: over 100
// noisy records 20 % fewer simulations and the same minima; 100 of 100 ±50 % starts still
// converge. Two such stages save 40 % but lose 3 of those 100 starts.
inline constexpr int kTimingOnlyStages = 1;
// Iteration cap of a continuation stage before the last: parameters the short window cannot see
// make Levenberg–Marquardt crawl, and the stage only has to reach the right basin.
inline constexpr int kStageIterations = 30;
// The direct whole-window fit of a start (besides the continuation) is finished only when its
// try, capped at kDirectTryIterations, ends below kDirectRetryFactor times the continued fit's
// cost.
inline constexpr double kDirectRetryFactor = 1.5;
inline constexpr int kDirectTryIterations = 10;
// Model samples per record step where a channel models the recorder's low-pass filter.
inline constexpr int kFilterOversample = 4;

struct FitOptions {
  int max_iterations = 100;
  double derivative_step = 1e-6;  // normalised (fraction of the bound width)
  bool polish_with_noise_weights = true;
  // Central instead of forward differences while iterating (the covariance always uses central).
  bool central_differences = false;
  int threads = 1;                // Ceres threads (the simulations themselves are serial)
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

// One channel of one record.
struct ChannelEstimate {
  std::string column;
  std::string link;
  std::string record;        // the record's source (file)
  std::string record_label;  // RecordLabels() of the fit's records
  double gain = 1.0;
  double gain_se = 0.0;
  double offset = 0.0;  // N·m
  double offset_se = 0.0;
  double weight = 0.0;  // 1/N·m, as used in the final fit
  double rms_residual = 0.0;  // N·m
  int samples = 0;
  std::vector<double> time_s;   // the window samples' times (s)
  std::vector<double> fitted;   // g·m + o at the window samples
  std::vector<double> measured;
};

struct LocalMinimum {
  double cost = 0.0;
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
  std::string ceres_brief;   // ceres::Solver::Summary::BriefReport() of the final fit
  std::string termination;
  int iterations = 0;
  int scan_points = 0;
  int starts = 0;
  int starts_at_best = 0;    // local fits reaching the best cost to 1e-6
  long simulations = 0;
  double wall_time_s = 0.0;
  double cost = 0.0;         // ½ Σ weighted residual²
  int residuals = 0;
  int fitted_quantities = 0;
  double noise_scale = 1.0;  // sqrt(2 cost / (N − P))
  double reciprocal_condition = 0.0;  // of the column-scaled Jacobian
  std::string BriefReport() const;
};

struct FitResult {
  std::vector<ParameterEstimate> parameters;
  std::vector<ChannelEstimate> channels;    // record by record, channels in config order
  // Parameters, then gain.<col>, offset.<col> (with @<record label> when there are several).
  std::vector<std::string> quantity_names;
  Eigen::MatrixXd correlation;              // over quantity_names
  std::vector<LocalMinimum> minima;
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

// Simulated torque of each channel's link at the record times in [begin, end); the scene's
// parameters as given. Returns false with a reason when the scene is invalid or the solver fails.
bool SimulateChannels(const driveline::Scene& scene, const Oscillogram& record,
                      const std::vector<ChannelSpec>& channels, int begin, int end,
                      std::vector<Eigen::VectorXd>* torques, std::string* why);

}  // namespace millkit::identify
