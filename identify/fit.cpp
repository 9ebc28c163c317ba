#include "identify/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "driveline/model.h"
#include "driveline/simulation.h"
#include "identify/fit_model.h"
#include "identify/instrument_filter.h"
#include "identify/multistart.h"
#include "identify/record_noise.h"
#include "identify/uncertainty.h"
#include "identify/verdict.h"
#include "io/input_error.h"

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
  require(derivative_step > 0.0 && derivative_step < 0.01,
          "derivative_step: must lie in (0, 0.01)");
  require(threads >= 1, "threads: must be >= 1");
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
  require(escalation_factor >= 1, "escalation_factor: must be >= 1");
  require(hops >= 0, "hops: must be >= 0");
  require(hop_radius > 0.0, "hop_radius: must be > 0");
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

bool SimulateChannels(const driveline::Scene& scene, const Oscillogram& record,
                      const std::vector<ChannelSpec>& channels, int begin, int end,
                      std::vector<Eigen::VectorXd>* torques, std::string* why) {
  try {
    driveline::Scene run = scene;
    run.duration_s = record.time_s[end - 1];
    driveline::SimulationOptions options;
    options.estimate_error = false;
    // A modelled recorder filter needs the signal from the record's start, kFilterOversample
    // points per record step (linear between them: the filter is exact for that).
    const bool filtered = std::any_of(channels.begin(), channels.end(),
                                      [](const ChannelSpec& c) { return c.lowpass_Hz > 0.0; });
    const int first = filtered ? 0 : begin;
    const int stride = filtered ? kFilterOversample : 1;
    std::vector<double> times;
    times.reserve(static_cast<size_t>(end - first - 1) * stride + 1);
    for (int k = first; k < end; ++k) {
      times.push_back(record.time_s[k]);
      if (k + 1 == end) break;
      const double step = (record.time_s[k + 1] - record.time_s[k]) / stride;
      for (int j = 1; j < stride; ++j) times.push_back(record.time_s[k] + j * step);
    }
    if (times.front() < 0.0) throw InputError(record.source + ": record time before 0");
    options.output_times = times;
    const driveline::Model model(std::move(run));
    const auto result = driveline::Simulate(model, options);
    if (!result.summary.success) {
      *why = result.summary.message;
      return false;
    }
    torques->resize(channels.size());
    std::vector<double> signal(times.size());
    for (size_t c = 0; c < channels.size(); ++c) {
      const auto column = result.link_torque_Nm.col(channels[c].link_index);
      for (size_t j = 0; j < times.size(); ++j) signal[j] = column(static_cast<int>(j));
      FirstOrderLowPass(channels[c].lowpass_Hz, times, &signal);
      auto& out = (*torques)[c];
      out.resize(end - begin);
      for (int k = begin; k < end; ++k)
        out(k - begin) = signal[static_cast<size_t>(k - first) * stride];
      if (!out.allFinite()) {
        *why = "non-finite torque";
        return false;
      }
    }
    return true;
  } catch (const InputError& error) {
    *why = error.what();
    return false;
  }
}

namespace {

std::string Short(double value) {
  std::ostringstream out;
  out << std::setprecision(3) << value;
  return out.str();
}

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

// The record cannot support the fit: the start point is reported unfitted, with its model trace
// where it simulates (gain 1, offset 0), so the engineer still gets the plot.
FitResult DegenerateResult(const FitModel& model, const RecordAssessment& assessment,
                           const std::vector<double>& start) {
  FitResult result;
  auto& summary = result.summary;
  for (int s = 0; s < model.parameters(); ++s) {
    const auto& free = model.free(s);
    ParameterEstimate e;
    e.name = model.slot(s).name;
    e.unit = free.parameter.unit;
    if (model.slot(s).record >= 0) e.record = model.record(model.slot(s).record).source;
    e.value = e.start = free.start;
    e.standard_error = std::numeric_limits<double>::quiet_NaN();
    e.lower = free.lower;
    e.upper = free.upper;
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

std::vector<int> FittedIndices(const FitModel& model) {
  const auto constant = model.ConstantIndices();
  std::vector<int> fitted;
  for (int j = 0; j < model.size(); ++j) {
    if (std::find(constant.begin(), constant.end(), j) == constant.end()) fitted.push_back(j);
  }
  return fitted;
}

}  // namespace

std::vector<double> CramerRaoBound(const driveline::Scene& scene, const Oscillogram& record,
                                   const FitConfig& config, const std::vector<double>& noise_Nm,
                                   const FitOptions& options) {
  options.Validate();
  const std::vector<Oscillogram> records = {record};
  ValidateFitConfig(config, records, "fit config");
  std::vector<double> weights;
  for (const double sigma : noise_Nm) weights.push_back(1.0 / sigma);
  weights.resize(config.channels.size(), 1.0);
  const FitModel model(scene, records, config, weights);
  std::vector<double> u(model.parameters());
  for (int i = 0; i < model.parameters(); ++i) {
    u[i] = model.Unit(i, model.free(i).parameter.Get(scene));
  }
  Eigen::VectorXd r;
  Eigen::MatrixXd jac;
  if (!model.FullJacobian(u, std::vector<Nuisance>(model.blocks()), options.derivative_step, &r,
                          &jac)) {
    throw InputError("Cramér–Rao bound: the scene does not simulate: " + model.last_failure());
  }
  const auto fitted = FittedIndices(model);
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

FitResult Fit(const driveline::Scene& scene, const std::vector<Oscillogram>& records,
              const FitConfig& config, const FitOptions& options) {
  options.Validate();
  ValidateFitConfig(config, records, "fit config");
  const auto clock_start = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  };
  const RecordAssessment assessment = AssessRecords(records, config);
  FitModel model(scene, records, config, assessment.weights);
  std::vector<double> start(model.parameters());
  for (int i = 0; i < model.parameters(); ++i) start[i] = model.Unit(i, model.free(i).start);
  if (!assessment.degenerate.empty()) {
    FitResult result = DegenerateResult(model, assessment, start);
    result.summary.wall_time_s = elapsed();
    return result;
  }

  FitResult result;
  auto& summary = result.summary;
  if (!std::isfinite(model.ProjectedCost(start.data()))) {
    summary.message = "the start point does not simulate: " + model.last_failure();
    summary.simulations = model.simulations();
    return result;
  }
  // The scan ranks its points on the first continuation stage, the short window after the onset
  // where impact timing decides; the best preselect_factor × starts go through that stage's fit.
  model.SetStage(ContinuationStages(model, options).front());
  auto starts = ScanStarts(model, config, options, start, config.starts * options.preselect_factor,
                           &summary.scan_points);
  starts = PreselectStarts(&model, options, starts, config.starts);
  std::vector<LocalFit> minima = RefineStarts(&model, options, starts);
  const auto lowest = [&minima] {
    int best = -1;
    for (int k = 0; k < static_cast<int>(minima.size()); ++k) {
      if (minima[k].usable && (best < 0 || minima[k].cost < minima[best].cost)) best = k;
    }
    return best;
  };
  int best = lowest();
  if (best < 0) {
    summary.message = "no start converged to a usable solution";
    if (!model.last_failure().empty())
      summary.message += " (last failure: " + model.last_failure() + ")";
    summary.simulations = model.simulations();
    return result;
  }
  // A best minimum that leaves the residual unexplained is most often a wrong basin: one more
  // search, with a scan escalation_factor times as dense, other points and twice the starts.
  const int fitted_count = static_cast<int>(FittedIndices(model).size());
  if (options.escalation_factor > 1 &&
      WorstResidualZ(model, assessment.noise, minima[best].u, fitted_count) > options.misfit_z) {
    FitConfig wider = config;
    wider.scan_points = config.scan_points * options.escalation_factor;
    wider.starts = config.starts * 2;
    wider.seed = config.seed + 1;
    int points = 0;
    model.SetStage(ContinuationStages(model, options).front());
    auto more = ScanStarts(model, wider, options, minima[best].u,
                           wider.starts * options.preselect_factor, &points);
    more = PreselectStarts(&model, options, more, wider.starts);
    const int offset = static_cast<int>(starts.size());
    for (auto fit : RefineStarts(&model, options, more)) {
      fit.start += offset;
      minima.push_back(std::move(fit));
    }
    starts.insert(starts.end(), more.begin(), more.end());
    summary.scan_points += points;
    summary.escalated = true;
    best = lowest();
  }
  // A coarse look along every parameter's axis from the best minimum; a probe below it is a
  // valley the starts missed: Levenberg–Marquardt goes on from there.
  // Basin hopping: a valley next door that every start missed.
  for (auto& point : HopPoints(model, minima[best].u, minima[best].cost, options)) {
    LocalFit fit = Refine(model, options, std::move(point), true, options.max_iterations);
    fit.start = -1;
    minima.push_back(std::move(fit));
  }
  best = lowest();
  std::vector<ProfileProbe> probes = ProfileProbes(model, minima[best].u, options);
  for (int restart = 0; restart < options.profile_restarts; ++restart) {
    const auto lowest_probe = [&](const std::vector<ProfileProbe>& candidates) {
      const ProfileProbe* lower = nullptr;
      for (const auto& probe : candidates) {
        if (probe.cost < minima[best].cost && (lower == nullptr || probe.cost < lower->cost)) {
          lower = &probe;
        }
      }
      return lower;
    };
    const ProfileProbe* lower = lowest_probe(probes);
    if (lower == nullptr) break;
    LocalFit fit = Refine(model, options, lower->u, true, options.max_iterations);
    fit.start = -1;
    minima.push_back(std::move(fit));
    const int previous = best;
    best = lowest();
    if (best == previous) break;
    probes = ProfileProbes(model, minima[best].u, options);
  }
  summary.starts = static_cast<int>(starts.size());
  const std::vector<double>& u = minima[best].u;

  // Residuals, Jacobian and covariance at the best minimum.
  Eigen::VectorXd r;
  std::vector<Nuisance> nuisance;
  std::vector<Eigen::VectorXd> m;
  Eigen::MatrixXd jac;
  if (!model.ProjectedResiduals(u.data(), &r, &nuisance, &m) ||
      !model.FullJacobian(u, nuisance, options.derivative_step, &r, &jac)) {
    summary.message = "the solution does not simulate: " + model.last_failure();
    summary.simulations = model.simulations();
    return result;
  }
  const auto fitted = FittedIndices(model);
  const double dof = static_cast<double>(model.residuals()) - static_cast<double>(fitted.size());
  summary.cost = 0.5 * r.squaredNorm();
  summary.residuals = model.residuals();
  summary.fitted_quantities = static_cast<int>(fitted.size());
  summary.noise_scale = std::sqrt(2.0 * summary.cost / std::max(1.0, dof));
  Eigen::MatrixXd covariance = Covariance(jac, fitted, summary.noise_scale);
  bool lower_found = false;
  const auto widening =
      ProfileWidening(model, u, covariance, summary.cost, summary.noise_scale, options,
                      std::vector<bool>(model.parameters(), true), probes, &lower_found);
  std::vector<std::string> widened;
  for (int i = 0; i < model.parameters(); ++i) {
    if (widening[i] > 1.0 && std::isfinite(widening[i])) {
      covariance.row(i) *= widening[i];
      covariance.col(i) *= widening[i];
      if (widening[i] > 1.05) widened.push_back(model.slot(i).name + " x" + Short(widening[i]));
    }
  }

  for (int i = 0; i < model.parameters(); ++i) {
    const auto& free = model.free(i);
    ParameterEstimate e;
    e.name = model.slot(i).name;
    e.unit = free.parameter.unit;
    if (model.slot(i).record >= 0) e.record = records[model.slot(i).record].source;
    e.value = model.Physical(i, u[i]);
    e.standard_error = std::sqrt(covariance(i, i)) * model.slot(i).map.PhysicalPerUnit(u[i]);
    e.start = free.start;
    e.lower = free.lower;
    e.upper = free.upper;
    e.at_bound = u[i] <= 1e-9 || u[i] >= 1.0 - 1e-9;
    result.parameters.push_back(e);
  }
  FlagUnidentifiable(model, jac, fitted, summary.noise_scale, options, &result);
  FlagPlateaus(model, probes, &result);
  FillChannels(model, m, nuisance, assessment.noise, &result);
  for (int b = 0; b < model.blocks(); ++b) {
    auto& c = result.channels[b];
    c.gain_se = std::sqrt(covariance(model.gain_index(b), model.gain_index(b)));
    c.offset_se =
        std::sqrt(covariance(model.offset_index(b), model.offset_index(b))) * model.block(b).scale;
  }
  for (const int j : fitted) {
    if (j < model.parameters()) {
      result.quantity_names.push_back(model.slot(j).name);
    } else {
      const int b = (j - model.parameters()) / 2;
      result.quantity_names.push_back(model.NuisanceName(b, j == model.gain_index(b)));
    }
  }
  result.correlation.resize(fitted.size(), fitted.size());
  for (size_t a = 0; a < fitted.size(); ++a) {
    for (size_t b = 0; b < fitted.size(); ++b) {
      result.correlation(a, b) =
          covariance(fitted[a], fitted[b]) /
          std::sqrt(covariance(fitted[a], fitted[a]) * covariance(fitted[b], fitted[b]));
    }
  }

  // Every local minimum, and how many starts reach the best one: some fit of theirs ends within
  // one standard error of it in every identifiable parameter, at a χ² within 1.
  std::vector<bool> reached(starts.size(), false);
  const double scale2 = summary.noise_scale * summary.noise_scale;
  for (const auto& fit : minima) {
    LocalMinimum minimum;
    minimum.cost = fit.cost;
    minimum.start = fit.start;
    minimum.iterations = static_cast<int>(fit.summary.iterations.size());
    minimum.converged = fit.converged;
    bool same = fit.usable && 2.0 * (fit.cost - minima[best].cost) <= scale2;
    for (int i = 0; i < model.parameters(); ++i) {
      minimum.values.push_back(model.Physical(i, fit.u[i]));
      const auto& e = result.parameters[i];
      if (e.identifiable && std::abs(minimum.values[i] - e.value) > e.standard_error) same = false;
    }
    if (same && fit.start >= 0) reached[fit.start] = true;
    result.minima.push_back(std::move(minimum));
  }
  summary.starts_at_best = static_cast<int>(std::count(reached.begin(), reached.end(), true));

  summary.success = true;
  const auto& chosen = minima[best].summary;
  summary.ceres_brief = chosen.BriefReport();
  summary.termination = ceres::TerminationTypeToString(chosen.termination_type);
  summary.iterations = static_cast<int>(chosen.iterations.size());
  if (lower_found) {
    summary.warnings.push_back("a probe " + Short(options.profile_step) +
                               " standard errors from the best point found a lower cost: the fit "
                               "had not reached its minimum");
  }
  JudgeFit(model, assessment.noise, minima, best, lower_found, options, &result);

  // Doubts that do not change the verdict.
  for (const auto& e : result.parameters) {
    if (e.at_bound) {
      summary.warnings.push_back(e.name + " = " + Short(e.value) + " " + e.unit +
                                 " is at a bound of [" + Short(e.lower) + ", " + Short(e.upper) +
                                 "]: the best value may lie outside");
    }
  }
  for (const auto& c : result.channels) {
    const std::string name = c.column + (records.size() > 1 ? "@" + c.record_label : "");
    if (c.gain_at_bound) {
      summary.warnings.push_back("channel " + name + ": gain " + Short(c.gain) +
                                 " is at its bound (gain_bounds)");
    }
    if (c.offset_at_bound) {
      summary.warnings.push_back("channel " + name + ": offset " + Short(c.offset) +
                                 " N*m is at its bound (offset_limit)");
    }
  }
  for (size_t b = 0; b < assessment.noise.size(); ++b) {
    if (!assessment.noise[b].from_quiet_stretch) {
      summary.warnings.push_back(
          "channel " + result.channels[b].column +
          ": no quiet stretch before the response; its noise was estimated from second "
          "differences, which a coarsely sampled response inflates");
    }
  }
  if (!widened.empty()) {
    std::string list;
    for (const auto& w : widened) list += (list.empty() ? "" : ", ") + w;
    summary.warnings.push_back(
        "standard errors widened where the cost is flatter than its "
        "linearisation: " +
        list);
  }
  summary.simulations = model.simulations();
  summary.wall_time_s = elapsed();
  return result;
}

}  // namespace millkit::identify
