#include "millkit/identify/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "identify/fit_model.h"
#include "identify/instrument_filter.h"
#include "identify/multistart.h"
#include "identify/record_noise.h"
#include "identify/uncertainty.h"
#include "identify/verdict.h"
#include "millkit/driveline/model.h"
#include "millkit/driveline/sensitivity.h"
#include "millkit/driveline/simulation.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::identify {

void FitOptions::Validate() const {
  const auto require = [](bool ok, const std::string& what) {
    if (!ok) throw InputError("fit option " + what);
  };
  require(max_iterations >= 1, "max_iterations: must be >= 1");
  require(function_tolerance > 0.0 && function_tolerance < 1.0,
          "function_tolerance: must lie in (0, 1)");
  require(parameter_tolerance > 0.0 && parameter_tolerance < 1.0,
          "parameter_tolerance: must lie in (0, 1)");
  require(remaining_step_se >= 0.0 && remaining_step_se <= 1.0,
          "remaining_step_se: must lie in [0, 1]");
  require(rough_step_se >= remaining_step_se && rough_step_se <= 1.0,
          "rough_step_se: must lie in [remaining_step_se, 1]");
  require(creep_iterations >= 0, "creep_iterations: must be >= 0");
  require(derivative_step > 0.0 && derivative_step < 0.01,
          "derivative_step: must lie in (0, 0.01)");
  require(threads >= 1 && threads <= 256, "threads: must lie in [1, 256]");
  require(first_stage_divisor >= 1.0 && first_stage_divisor <= 1e4,
          "first_stage_divisor: must lie in [1, 1e4]");
  require(continuation_ratio > 1.0 && continuation_ratio <= 1e4,
          "continuation_ratio: must lie in (1, 1e4]");
  require(timing_only_stages >= 0, "timing_only_stages: must be >= 0");
  require(stage_iterations >= 1, "stage_iterations: must be >= 1");
  require(direct_retry_factor >= 1.0, "direct_retry_factor: must be >= 1");
  require(direct_try_iterations >= 1, "direct_try_iterations: must be >= 1");
  require(distinct_start >= 0.0 && distinct_start < 1.0, "distinct_start: must lie in [0, 1)");
  require(rank_tolerance > 0.0 && rank_tolerance < 1.0, "rank_tolerance: must lie in (0, 1)");
  require(unidentifiable_fraction > 0.0, "unidentifiable_fraction: must be > 0");
  require(profile_step > 0.0, "profile_step: must be > 0");
  require(profile_points >= 0, "profile_points: must be >= 0");
  require(profile_chi2 > 0.0, "profile_chi2: must be > 0");
  require(profile_restarts >= 0, "profile_restarts: must be >= 0");
  require(profile_relax_widening >= 0.0, "profile_relax_widening: must be >= 0");
  require(profile_bend_ratio >= 0.0, "profile_bend_ratio: must be >= 0");
  require(profile_iterations >= 1, "profile_iterations: must be >= 1");
  require(profile_relax_reach >= profile_step, "profile_relax_reach: must be >= profile_step");
  require(curved_valley_ratio >= 0.0, "curved_valley_ratio: must be >= 0");
  require(curved_valley_iterations >= 1, "curved_valley_iterations: must be >= 1");
  require(bound_walk_se >= 0.0 && bound_walk_se <= 16.0, "bound_walk_se: must be in [0, 16]");
  require(open_gap_points >= 0 && open_gap_points <= 20, "open_gap_points: must be in [0, 20]");
  require(gap_profile_points >= 0 && gap_profile_points <= 64,
          "gap_profile_points: must be in [0, 64]");
  require(escalation_factor >= 1, "escalation_factor: must be >= 1");
  require(hops >= 0, "hops: must be >= 0");
  require(hop_radius > 0.0, "hop_radius: must be > 0");
  require(gap_kick >= 0.0 && gap_kick < 1.0, "gap_kick: must be in [0, 1)");
  require(gap_kick_levels >= 1 && gap_kick_levels <= 8, "gap_kick_levels: must be in [1, 8]");
  require(rejoin_se >= 0.0 && rejoin_se <= 1.0, "rejoin_se: must lie in [0, 1]");
  require(preselect_factor >= 1, "preselect_factor: must be >= 1");
  require(misfit_z > 0.0, "misfit_z: must be > 0");
  require(ambiguity_chi2 >= 0.0, "ambiguity_chi2: must be >= 0");
  require(distinct_minimum_se > 0.0, "distinct_minimum_se: must be > 0");
}

std::string FitSummary::BriefReport() const {
  std::ostringstream out;
  out << "fit: " << (success ? verdict : "FAILED") << ", cost " << cost << ", " << iterations
      << " iterations, " << starts_at_best << "/" << starts << " starts reach the best minimum ("
      << scan_points << " scan points), " << simulations << " simulations, " << wall_time_s
      << " s, noise scale " << noise_scale;
  if (!success) out << ": " << message;
  return out.str();
}

double TimeOrigin(const FitConfig& config, const Oscillogram& record) {
  return config.time_origin_s ? *config.time_origin_s : record.time_s.front();
}

const char* DerivativesName(Derivatives derivatives) {
  switch (derivatives) {
    case Derivatives::kSensitivity:
      return "sensitivity";
    case Derivatives::kForward:
      return "forward";
    case Derivatives::kCentral:
      return "central";
  }
  return "sensitivity";
}

bool ParseDerivatives(const std::string& text, Derivatives* derivatives) {
  for (const auto kind :
       {Derivatives::kSensitivity, Derivatives::kForward, Derivatives::kCentral}) {
    if (text == DerivativesName(kind)) {
      *derivatives = kind;
      return true;
    }
  }
  return false;
}

namespace {

// The run a record's channels need: the output times (the record's, or oversampled for filters
// applied after the run) and the channels' links.
struct ChannelRun {
  driveline::SimulationOptions options;
  bool filtered = false;  // the recorder filters are applied after the run
  int first = 0;          // the record step of the first output time
  int stride = 1;         // output times per record step
  std::vector<int> links;
  size_t samples = 0;
};

ChannelRun PrepareChannelRun(const Oscillogram& record, double origin_s,
                             const std::vector<ChannelSpec>& channels, int begin, int end) {
  ChannelRun run;
  run.options.estimate_error = false;
  // A modelled recorder filter runs inside the model (Link::recorder_lowpass_Hz: exact at the
  // record's times, at any cutoff) when every channel of a link has the same one (RunScene).
  // Otherwise the model is sampled kFilterOversample times per record step from the record's
  // start and each channel's filter applied as linear between the points.
  for (const auto& a : channels) {
    for (const auto& b : channels) {
      if (a.link_index == b.link_index && a.lowpass_Hz != b.lowpass_Hz) run.filtered = true;
    }
  }
  run.first = run.filtered ? 0 : begin;
  run.stride = run.filtered ? kFilterOversample : 1;
  std::vector<double> times;
  times.reserve(static_cast<size_t>(end - run.first - 1) * run.stride + 1);
  for (int k = run.first; k < end; ++k) {
    times.push_back(record.time_s[k] - origin_s);
    if (k + 1 == end) break;
    const double step = (record.time_s[k + 1] - record.time_s[k]) / run.stride;
    for (int j = 1; j < run.stride; ++j) times.push_back(record.time_s[k] - origin_s + j * step);
  }
  if (times.front() < 0.0) {
    throw InputError(record.source + ": record time " + std::to_string(record.time_s[run.first]) +
                     " s lies before the time origin " + std::to_string(origin_s) + " s");
  }
  for (const auto& channel : channels) {
    if (std::find(run.links.begin(), run.links.end(), channel.link_index) == run.links.end()) {
      run.links.push_back(channel.link_index);
    }
  }
  run.samples = times.size();
  run.options.output_times = std::move(times);
  return run;
}

// The scene a record's run simulates: to the record's last time, with the channels' recorder
// filters inside the model unless they follow the run.
driveline::Scene RunScene(const ChannelRun& run, const driveline::Scene& scene,
                          const std::vector<ChannelSpec>& channels) {
  driveline::Scene simulated = scene;
  simulated.duration_s = run.options.output_times->back();
  if (!run.filtered) {
    for (const auto& channel : channels) {
      simulated.links[channel.link_index].recorder_lowpass_Hz = channel.lowpass_Hz;
    }
  }
  return simulated;
}

// A signal of the run's output times at the record steps in [begin, end) (through the channel's
// recorder filter, linear between the samples, when the filters follow the run). `signal` is
// filtered in place.
void ToRecordSteps(const ChannelRun& run, const ChannelSpec& channel, int begin, int end,
                   std::vector<double>* signal, Eigen::Ref<Eigen::VectorXd> out) {
  if (run.filtered) FirstOrderLowPass(channel.lowpass_Hz, *run.options.output_times, signal);
  for (int k = begin; k < end; ++k) {
    out(k - begin) = (*signal)[static_cast<size_t>(k - run.first) * run.stride];
  }
}

size_t LinkSlot(const ChannelRun& run, const ChannelSpec& channel) {
  return std::find(run.links.begin(), run.links.end(), channel.link_index) - run.links.begin();
}

// Each channel's derivatives from the sensitivities of its link's torque.
void ChannelDerivativesFrom(const ChannelRun& run, const std::vector<ChannelSpec>& channels,
                            int begin, int end, const driveline::SensitivityResult& sensitivities,
                            std::vector<Eigen::MatrixXd>* derivatives) {
  const auto count = static_cast<Eigen::Index>(sensitivities.link_torque.size());
  derivatives->resize(channels.size());
  std::vector<double> signal(run.samples);
  for (size_t c = 0; c < channels.size(); ++c) {
    const auto link = static_cast<Eigen::Index>(LinkSlot(run, channels[c]));
    auto& derivative = (*derivatives)[c];
    derivative.resize(end - begin, count);
    for (Eigen::Index j = 0; j < count; ++j) {
      const auto column = sensitivities.link_torque[j].col(link);
      for (size_t k = 0; k < run.samples; ++k) signal[k] = column(static_cast<Eigen::Index>(k));
      ToRecordSteps(run, channels[c], begin, end, &signal, derivative.col(j));
    }
  }
}

// SimulateChannels, either overload: derivatives when `derivatives`, the run kept when `kept`.
bool RunChannels(const driveline::Scene& scene, const Oscillogram& record, double origin_s,
                 const std::vector<ChannelSpec>& channels, int begin, int end,
                 std::vector<Eigen::VectorXd>* torques, std::string* why,
                 const std::vector<driveline::SceneParameter>& parameters,
                 std::vector<Eigen::MatrixXd>* derivatives, std::string* unavailable,
                 driveline::RecordedRun* kept) {
  try {
    ChannelRun run = PrepareChannelRun(record, origin_s, channels, begin, end);
    driveline::Scene simulated = RunScene(run, scene, channels);
    const auto& links = run.links;
    // The plain run streams only the channels' link torques (no sample matrices).
    std::vector<std::vector<double>> link_signal(links.size(), std::vector<double>(run.samples));
    driveline::SensitivityResult sensitivities;
    if (derivatives != nullptr) {
      sensitivities =
          driveline::SimulateWithSensitivities(simulated, parameters, run.options, links);
      *unavailable = sensitivities.unavailable;
    } else {
      run.options.keep_samples = false;
      run.options.sample_sink = [&](const driveline::OutputSample& sample) {
        for (size_t i = 0; i < links.size(); ++i) {
          link_signal[i][sample.index] = sample.link_torque_Nm[links[i]];
        }
      };
      if (kept != nullptr) {
        *kept = driveline::RecordedRun(simulated, run.options);
        sensitivities.simulation = kept->result();
      } else {
        sensitivities.simulation =
            driveline::Simulate(driveline::Model(std::move(simulated)), run.options);
      }
    }
    const auto& result = sensitivities.simulation;
    if (!result.summary.success) {
      *why = result.summary.message;
      return false;
    }
    if (derivatives != nullptr) {
      for (size_t i = 0; i < links.size(); ++i) {
        for (size_t j = 0; j < run.samples; ++j) {
          link_signal[i][j] = result.link_torque_Nm(static_cast<Eigen::Index>(j), links[i]);
        }
      }
    }
    torques->resize(channels.size());
    std::vector<double> signal;
    for (size_t c = 0; c < channels.size(); ++c) {
      auto& out = (*torques)[c];
      out.resize(end - begin);
      signal = link_signal[LinkSlot(run, channels[c])];
      ToRecordSteps(run, channels[c], begin, end, &signal, out);
      if (!out.allFinite()) {
        *why = "non-finite torque";
        return false;
      }
    }
    if (derivatives != nullptr && unavailable->empty()) {
      ChannelDerivativesFrom(run, channels, begin, end, sensitivities, derivatives);
    }
    return true;
  } catch (const InputError& error) {
    *why = error.what();
    return false;
  }
}

}  // namespace

bool SimulateChannels(const driveline::Scene& scene, const Oscillogram& record, double origin_s,
                      const std::vector<ChannelSpec>& channels, int begin, int end,
                      std::vector<Eigen::VectorXd>* torques, std::string* why,
                      driveline::RecordedRun* kept) {
  return RunChannels(scene, record, origin_s, channels, begin, end, torques, why, {}, nullptr,
                     nullptr, kept);
}

bool SimulateChannels(const driveline::Scene& scene, const Oscillogram& record, double origin_s,
                      const std::vector<ChannelSpec>& channels, int begin, int end,
                      std::vector<Eigen::VectorXd>* torques, std::string* why,
                      const std::vector<driveline::SceneParameter>& parameters,
                      std::vector<Eigen::MatrixXd>* derivatives, std::string* unavailable) {
  return RunChannels(scene, record, origin_s, channels, begin, end, torques, why, parameters,
                     derivatives, unavailable, nullptr);
}

bool ChannelDerivatives(const driveline::RecordedRun& kept, const Oscillogram& record,
                        double origin_s, const std::vector<ChannelSpec>& channels, int begin,
                        int end, const std::vector<driveline::SceneParameter>& parameters,
                        std::vector<Eigen::MatrixXd>* derivatives, std::string* unavailable,
                        std::string* why) {
  try {
    const ChannelRun run = PrepareChannelRun(record, origin_s, channels, begin, end);
    const driveline::SensitivityResult sensitivities =
        driveline::SimulateWithSensitivities(kept, parameters, run.links);
    if (!sensitivities.simulation.summary.success) {
      *why = sensitivities.simulation.summary.message;
      return false;
    }
    *unavailable = sensitivities.unavailable;
    if (unavailable->empty()) {
      if (sensitivities.link_torque.empty() ||
          sensitivities.link_torque.front().rows() != static_cast<Eigen::Index>(run.samples)) {
        throw std::logic_error(
            "ChannelDerivatives: the kept run has another output grid than this record window");
      }
      ChannelDerivativesFrom(run, channels, begin, end, sensitivities, derivatives);
    }
    return true;
  } catch (const InputError& error) {
    *why = error.what();
    return false;
  }
}

namespace {

// What the records say before any model runs: each block's noise and weight, and why the records
// cannot support the fit, if they cannot.
struct RecordAssessment {
  std::vector<ChannelNoise> noise;  // per block
  std::vector<double> weights;
  std::vector<std::string> degenerate;
};

RecordAssessment AssessRecords(const std::vector<Oscillogram>& records, const FitConfig& config) {
  RecordAssessment a;
  int fitted = static_cast<int>(config.free.size());
  for (const auto& c : config.channels) fitted += (c.fit_gain ? 1 : 0) + (c.fit_offset ? 1 : 0);
  int after_onset = 0;
  for (const auto& record : records) {
    std::vector<int> columns;
    for (const auto& c : config.channels) columns.push_back(record.ChannelIndex(c.column));
    const int quiet_end = QuietStretchEnd(record, columns);
    const int onset = static_cast<int>(quiet_end / (1.0 - kQuietMargin));
    const auto [begin, end] = record.WindowRange(config.window_start_s, config.window_end_s);
    for (size_t c = 0; c < columns.size(); ++c) {
      const ChannelNoise noise = EstimateChannelNoise(record, columns[c], quiet_end, begin, end);
      const std::string why = DegenerateColumn(record, columns[c], begin, end, noise.sigma_Nm);
      if (!why.empty()) a.degenerate.push_back(why);
      a.noise.push_back(noise);
      const auto& weight = config.channels[c].weight;
      a.weights.push_back(weight ? *weight : noise.sigma_Nm > 0.0 ? 1.0 / noise.sigma_Nm : 1.0);
      after_onset += std::max(0, end - std::max(begin, onset));
    }
  }
  if (after_onset < fitted) {
    a.degenerate.push_back("the window holds " + std::to_string(after_onset) +
                           " samples after the response starts, fewer than the " +
                           std::to_string(fitted) + " fitted quantities");
  }
  return a;
}

std::string NoiseSource(const ChannelNoise& noise) {
  return noise.from_quiet_stretch
             ? "quiet stretch of " + std::to_string(noise.quiet_samples) + " samples"
             : "second differences";
}

// Per-block results: fitted trace, residual, nuisance.
void FillChannels(const FitModel& model, const std::vector<Eigen::VectorXd>& m,
                  const std::vector<Nuisance>& nuisance, const std::vector<ChannelNoise>& noise,
                  FitResult* result) {
  for (int b = 0; b < model.blocks(); ++b) {
    const auto& block = model.block(b);
    const auto& spec = model.channel_spec(b);
    const auto& record = model.record(block.record);
    ChannelEstimate e;
    e.column = spec.column;
    e.link = spec.link;
    e.record = record.source;
    e.record_label = model.label(block.record);
    e.gain = nuisance[b].gain;
    e.offset = nuisance[b].offset_Nm;
    e.gain_at_bound = nuisance[b].gain_at_bound;
    e.offset_at_bound = nuisance[b].offset_at_bound;
    e.weight = block.weight;
    e.noise = noise[b].sigma_Nm;
    e.noise_source = NoiseSource(noise[b]);
    const int n = static_cast<int>(block.measured.size());
    e.samples = n;
    e.time_s.assign(record.time_s.begin() + block.begin, record.time_s.begin() + block.end);
    e.measured.assign(block.measured.data(), block.measured.data() + n);
    if (static_cast<int>(m[b].size()) == n) {
      const Eigen::VectorXd fitted = e.gain * m[b].array() + e.offset;
      e.fitted.assign(fitted.data(), fitted.data() + n);
      e.rms_residual = (fitted - block.measured).norm() / std::sqrt(n);
    } else {
      e.fitted.assign(n, std::numeric_limits<double>::quiet_NaN());
      e.rms_residual = std::numeric_limits<double>::quiet_NaN();
    }
    result->channels.push_back(std::move(e));
  }
}

// What the config says of scene slot s (name, unit, record, start, bounds); value and standard
// error are the caller's.
ParameterEstimate EstimateFrame(const FitModel& model, int s) {
  const auto& free = model.free(s);
  ParameterEstimate e;
  e.name = model.slot(s).name;
  e.unit = free.parameter.unit;
  if (model.slot(s).record >= 0) e.record = model.record(model.slot(s).record).source;
  e.start = free.start;
  e.lower = free.lower;
  e.upper = free.upper;
  return e;
}

// The record cannot support the fit: the start point is reported unfitted, with its model trace
// where it simulates (gain 1, offset 0), so the engineer still gets the plot.
FitResult DegenerateResult(const FitModel& model, const RecordAssessment& assessment,
                           const std::vector<double>& start) {
  FitResult result;
  auto& summary = result.summary;
  for (int s = 0; s < model.parameters(); ++s) {
    ParameterEstimate e = EstimateFrame(model, s);
    e.value = e.start;
    e.standard_error = std::numeric_limits<double>::quiet_NaN();
    e.identifiable = false;
    e.why_not = "not fitted: the record cannot support the fit";
    result.parameters.push_back(e);
  }
  std::vector<Eigen::VectorXd> m;
  if (!model.Torques(start.data(), &m)) m.assign(model.blocks(), Eigen::VectorXd());
  FillChannels(model, m, std::vector<Nuisance>(model.blocks()), assessment.noise, &result);
  summary.success = true;
  summary.verdict = "degenerate";
  summary.warnings = assessment.degenerate;
  summary.message = "the record cannot support the fit";
  summary.residuals = model.residuals();
  summary.simulations = model.simulations();
  summary.cost = summary.noise_scale = std::numeric_limits<double>::quiet_NaN();
  return result;
}

}  // namespace

std::vector<double> CramerRaoBound(const driveline::Scene& scene, const Oscillogram& record,
                                   const FitConfig& config, const std::vector<double>& noise_Nm,
                                   const FitOptions& options) {
  options.Validate();
  const std::vector<Oscillogram> records = {record};
  ValidateFitConfig(config, records, "fit config");
  std::vector<double> weights;
  weights.reserve(noise_Nm.size());
  for (const double sigma : noise_Nm) weights.push_back(1.0 / sigma);
  weights.resize(config.channels.size(), 1.0);
  const FitModel model(scene, records, config, weights);
  std::vector<double> u(model.parameters());
  for (int i = 0; i < model.parameters(); ++i) {
    u[i] = model.Unit(i, model.free(i).parameter.Get(scene));
  }
  Eigen::VectorXd r;
  Eigen::MatrixXd jac;
  if (!model.FullJacobian(u, std::vector<Nuisance>(model.blocks()), options.derivative_step,
                          options.derivatives, &r, &jac)) {
    throw InputError("Cramér–Rao bound: the scene does not simulate: " + model.last_failure());
  }
  const auto fitted = model.FittedIndices();
  Eigen::MatrixXd reduced(jac.rows(), fitted.size());
  for (size_t j = 0; j < fitted.size(); ++j) reduced.col(j) = jac.col(fitted[j]);
  const Eigen::MatrixXd information = reduced.transpose() * reduced;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(information);
  const Eigen::MatrixXd inverse =
      ldlt.solve(Eigen::MatrixXd::Identity(information.rows(), information.cols()));
  std::vector<double> bound;
  for (int i = 0; i < model.parameters(); ++i) {
    const double variance = inverse(i, i);
    bound.push_back(variance > 0.0 && std::isfinite(variance)
                        ? std::sqrt(variance) * model.slot(i).map.PhysicalPerUnit(u[i])
                        : std::numeric_limits<double>::quiet_NaN());
  }
  return bound;
}

FitResult Fit(const driveline::Scene& scene, const Oscillogram& record, const FitConfig& config,
              const FitOptions& options) {
  return Fit(scene, std::vector<Oscillogram>{record}, config, options);
}

namespace {

// The best minimum described: values and standard errors (covariance widened where the profile is
// flatter), identifiability, channels, correlations. Sets `lower` to the lowest point a profile
// probe found below the minimum's cost (empty when none). False when the best minimum does not
// simulate.
bool DescribeBest(const FitModel& model, const Search& search, const RecordAssessment& assessment,
                  const FitOptions& options, FitResult* result,
                  std::optional<ProfileProbe>* lower) {
  auto& summary = result->summary;
  const std::vector<double>& u = search.minima[search.best].u;
  Eigen::VectorXd r;
  std::vector<Nuisance> nuisance;
  std::vector<Eigen::VectorXd> m;
  Eigen::MatrixXd jac;
  if (!model.ProjectedResiduals(u.data(), &r, &nuisance, &m) ||
      !model.FullJacobian(u, nuisance, options.derivative_step, options.derivatives, &r, &jac)) {
    return false;
  }
  const auto fitted = model.FittedIndices();
  const double dof = static_cast<double>(model.residuals()) - static_cast<double>(fitted.size());
  summary.cost = 0.5 * r.squaredNorm();
  summary.residuals = model.residuals();
  summary.fitted_quantities = static_cast<int>(fitted.size());
  summary.noise_scale = std::sqrt(2.0 * summary.cost / std::max(1.0, dof));
  Eigen::MatrixXd covariance = Covariance(jac, fitted, summary.noise_scale);
  const auto widening =
      ProfileWidening(model, u, jac, fitted, covariance, summary.cost, summary.noise_scale, options,
                      search.probes, search.bound_walks, lower);
  const auto alone = GapRangeWidening(model, u, covariance, summary.cost, summary.noise_scale,
                                      options, search.gap_points);
  const Eigen::MatrixXd linearised = covariance;
  Eigen::MatrixXd along_profiles = covariance;  // for the plateau test (FlagPlateaus)
  WidenAlongProfiles(widening, &along_profiles);
  WidenAlongProfiles(widening, &covariance, alone);
  std::string widened;
  for (int i = 0; i < model.parameters(); ++i) {
    const double factor = std::sqrt(covariance(i, i) / linearised(i, i));
    if (factor > 1.05) {
      widened += (widened.empty() ? "" : ", ") + model.slot(i).name + " x" + ShortNumber(factor);
    }
  }
  if (!widened.empty()) {
    summary.warnings.push_back(
        "standard errors widened where the cost is flatter than its linearisation: " + widened);
  }

  for (int i = 0; i < model.parameters(); ++i) {
    ParameterEstimate e = EstimateFrame(model, i);
    e.value = model.Physical(i, u[i]);
    e.standard_error = std::sqrt(covariance(i, i)) * model.slot(i).map.PhysicalPerUnit(u[i]);
    e.at_bound = u[i] <= kAtBound || u[i] >= 1.0 - kAtBound;
    result->parameters.push_back(e);
  }
  FlagUnidentifiable(model, jac, fitted, summary.noise_scale, options, result);
  std::vector<double> plateau_errors(model.parameters());
  for (int i = 0; i < model.parameters(); ++i) {
    plateau_errors[i] = std::sqrt(along_profiles(i, i)) * model.slot(i).map.PhysicalPerUnit(u[i]);
  }
  FlagPlateaus(model, search.probes, plateau_errors, result);
  FillChannels(model, m, nuisance, assessment.noise, result);
  for (int b = 0; b < model.blocks(); ++b) {
    auto& c = result->channels[b];
    c.gain_se = std::sqrt(covariance(model.gain_index(b), model.gain_index(b)));
    c.offset_se =
        std::sqrt(covariance(model.offset_index(b), model.offset_index(b))) * model.block(b).scale;
  }
  for (const int j : fitted) {
    if (j < model.parameters()) {
      result->quantity_names.push_back(model.slot(j).name);
    } else {
      const int b = (j - model.parameters()) / 2;
      result->quantity_names.push_back(model.NuisanceName(b, j == model.gain_index(b)));
    }
  }
  result->correlation.resize(fitted.size(), fitted.size());
  for (size_t a = 0; a < fitted.size(); ++a) {
    for (size_t b = 0; b < fitted.size(); ++b) {
      result->correlation(a, b) =
          covariance(fitted[a], fitted[b]) /
          std::sqrt(covariance(fitted[a], fitted[a]) * covariance(fitted[b], fitted[b]));
    }
  }
  return true;
}

// Every local minimum, and how many starts reach the best one: some fit of theirs ends within
// one standard error of it in every identifiable parameter, at a χ² within 1.
void ListMinima(const FitModel& model, const Search& search, FitResult* result) {
  auto& summary = result->summary;
  std::vector<bool> reached(search.starts, false);
  const double scale2 = summary.noise_scale * summary.noise_scale;
  const LocalFit& best = search.minima[search.best];
  for (const auto& fit : search.minima) {
    LocalMinimum minimum;
    minimum.cost = fit.cost;
    minimum.start = fit.start;
    minimum.iterations = static_cast<int>(fit.summary.iterations.size());
    minimum.converged = fit.converged;
    bool same = fit.usable && 2.0 * (fit.cost - best.cost) <= scale2;
    for (int i = 0; i < model.parameters(); ++i) {
      minimum.values.push_back(model.Physical(i, fit.u[i]));
      const auto& e = result->parameters[i];
      if (e.identifiable && std::abs(minimum.values[i] - e.value) > e.standard_error) same = false;
    }
    if (same && fit.start >= 0) reached[fit.start] = true;
    result->minima.push_back(std::move(minimum));
  }
  summary.starts = search.starts;
  summary.scan_points = search.scan_points;
  summary.escalated = search.escalated;
  summary.starts_at_best = static_cast<int>(std::count(reached.begin(), reached.end(), true));
  summary.ceres_brief = best.summary.BriefReport();
  summary.termination = ceres::TerminationTypeToString(best.summary.termination_type);
  summary.iterations = static_cast<int>(best.summary.iterations.size());
}

// Doubts that do not change the verdict: values at bounds, noise without a quiet stretch.
void AddDoubts(const RecordAssessment& assessment, bool several_records, FitResult* result) {
  auto& warnings = result->summary.warnings;
  for (const auto& e : result->parameters) {
    if (e.at_bound) {
      warnings.push_back(e.name + " = " + ShortNumber(e.value) + " " + e.unit +
                         " is at a bound of [" + ShortNumber(e.lower) + ", " +
                         ShortNumber(e.upper) + "]: the best value may lie outside");
    }
  }
  for (size_t b = 0; b < result->channels.size(); ++b) {
    const auto& c = result->channels[b];
    const std::string name = c.column + (several_records ? "@" + c.record_label : "");
    if (c.gain_at_bound) {
      warnings.push_back("channel " + name + ": gain " + ShortNumber(c.gain) +
                         " is at its bound (gain_bounds); a gain far from 1 can be a wrong "
                         "unit: give the channel's unit (N*m, kN*m or MN*m) in its [[channel]] "
                         "or the record's units row");
    }
    if (c.offset_at_bound) {
      warnings.push_back("channel " + name + ": offset " + ShortNumber(c.offset) +
                         " N*m is at its bound (offset_limit)");
    }
    if (!assessment.noise[b].from_quiet_stretch) {
      warnings.push_back("channel " + name +
                         ": no quiet stretch before the response; its noise was estimated from "
                         "second differences, which a coarsely sampled response inflates");
    }
  }
}

FitResult FitInNewtonMetres(const driveline::Scene& scene, const std::vector<Oscillogram>& records,
                            const FitConfig& config, const FitOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  };
  // The records' noise (the fixed weights) and whether they can support a fit at all.
  const RecordAssessment assessment = AssessRecords(records, config);
  std::vector<double> origins;
  origins.reserve(records.size());
  for (const auto& record : records) origins.push_back(TimeOrigin(config, record));
  FitModel model(scene, records, config, assessment.weights);
  model.set_progress(options.progress);
  std::vector<double> start(model.parameters());
  for (int i = 0; i < model.parameters(); ++i) start[i] = model.Unit(i, model.free(i).start);
  if (!assessment.degenerate.empty()) {
    FitResult result = DegenerateResult(model, assessment, start);
    result.time_origins_s = origins;
    result.summary.wall_time_s = elapsed();
    return result;
  }
  FitResult result;
  result.time_origins_s = origins;
  auto& summary = result.summary;
  const auto fail = [&](const std::string& message) {
    summary.message = message;
    summary.simulations = model.simulations();
    summary.wall_time_s = elapsed();
    return result;
  };
  if (!std::isfinite(model.ProjectedCost(start.data()))) {
    return fail("the start point does not simulate: " + model.last_failure());
  }
  // Every local minimum the global search finds, the best one checked around.
  Search search = GlobalSearch(&model, config, options, assessment.noise, start);
  if (search.best < 0) {
    std::string message = "no start converged to a usable solution";
    if (!model.last_failure().empty()) message += " (last failure: " + model.last_failure() + ")";
    return fail(message);
  }
  // Its values, standard errors and identifiability; then the verdict. A profile probe below the
  // best minimum (Levenberg–Marquardt stopped on the misfit's rough floor, or in a valley that
  // goes on) is gone on from, as an axis probe below it is in the search, up to
  // profile_restarts times.
  std::optional<ProfileProbe> lower;
  for (int restart = 0;; ++restart) {
    model.set_activity("standard errors");
    FitResult described = result;
    if (!DescribeBest(model, search, assessment, options, &described, &lower)) {
      return fail("the solution does not simulate: " + model.last_failure());
    }
    if (!lower.has_value() || restart >= options.profile_restarts) {
      result = std::move(described);
      break;
    }
    model.set_activity("going on below the best minimum");
    if (!GoOnBelowBest(&model, options, lower->u, &search)) {
      result = std::move(described);
      break;
    }
  }
  const bool lower_found = lower.has_value();
  ListMinima(model, search, &result);
  summary.success = true;
  if (lower_found) {
    summary.warnings.push_back(
        "a probe around the best point (along a profile, up to " +
        ShortNumber(options.profile_relax_reach) +
        " standard errors away, or on a parameter's axis) found a lower cost: the fit had not "
        "reached its minimum");
  }
  JudgeFit(model, assessment.noise, search.minima, search.best, lower_found, options, &result);
  AddDoubts(assessment, records.size() > 1, &result);
  summary.simulations = model.simulations();
  summary.wall_time_s = elapsed();
  return result;
}

}  // namespace

FitResult Fit(const driveline::Scene& scene, const std::vector<Oscillogram>& records,
              const FitConfig& config, const FitOptions& options) {
  options.Validate();
  ValidateFitConfig(config, records, "fit config");
  // Channels logged in kN·m or MN·m are fitted in N·m and reported in their own unit.
  bool all_Nm = true;
  for (const auto& c : config.channels) all_Nm = all_Nm && c.unit.newton_metres == 1.0;
  std::vector<Oscillogram> scaled;
  if (!all_Nm) {
    scaled = records;
    for (auto& record : scaled) {
      for (const auto& c : config.channels) {
        for (double& v : record.values[record.ChannelIndex(c.column)]) v *= c.unit.newton_metres;
      }
    }
  }
  FitOptions chosen = options;
  if (config.derivatives) chosen.derivatives = *config.derivatives;
  FitResult result = FitInNewtonMetres(scene, all_Nm ? records : scaled, config, chosen);
  for (auto& e : result.channels) {
    const auto spec = std::find_if(config.channels.begin(), config.channels.end(),
                                   [&e](const ChannelSpec& c) { return c.column == e.column; });
    e.unit = spec->unit.name;
    const double f = spec->unit.newton_metres;
    if (f == 1.0) continue;
    for (double* v : {&e.offset, &e.offset_se, &e.noise, &e.rms_residual}) *v /= f;
    e.weight *= f;
    for (double& v : e.measured) v /= f;
    for (double& v : e.fitted) v /= f;
  }
  return result;
}

}  // namespace millkit::identify
