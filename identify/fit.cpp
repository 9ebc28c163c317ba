#include "identify/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>

#include <ceres/ceres.h>

#include "driveline/model.h"
#include "driveline/simulation.h"
#include "identify/instrument_filter.h"
#include "io/input_error.h"
#include "io/toml_section.h"

namespace millkit::identify {

void FitOptions::Validate() const {
  if (max_iterations < 1) throw InputError("fit option max_iterations: must be >= 1");
  if (!(derivative_step > 0.0 && derivative_step < 0.01)) {
    throw InputError("fit option derivative_step: must lie in (0, 0.01)");
  }
  if (threads < 1) throw InputError("fit option threads: must be >= 1");
}

std::string FitSummary::BriefReport() const {
  std::ostringstream out;
  out << "fit: " << (success ? "converged" : "FAILED") << ", cost " << cost << ", "
      << iterations << " iterations, " << starts_at_best << "/" << starts
      << " starts reach the best minimum (" << scan_points << " scan points), " << simulations
      << " simulations, " << wall_time_s << " s, noise scale " << noise_scale;
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
      for (int k = begin; k < end; ++k) out(k - begin) = signal[static_cast<size_t>(k - first) * stride];
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

// Fitted vector θ = [u_1 … u_P, g_1, ô_1, …, g_C, ô_C]: u_i = (p_i − lower_i)/(upper_i − lower_i)
// in [0, 1], g_c the gain, ô_c = o_c / S_c the offset over the channel's peak |y|.
class FitModel {
 public:
  FitModel(const driveline::Scene& scene, const Oscillogram& record, const FitConfig& config)
      : scene_(scene), record_(record), config_(config) {
    std::tie(begin_, end_) = record.WindowRange(config.window_start_s, config.window_end_s);
    full_end_ = end_;
    for (const auto& c : config.channels) {
      double peak = 0.0;
      for (int k = begin_; k < end_; ++k) {
        peak = std::max(peak, std::abs(record.values[c.record_channel][k]));
      }
      scale_.push_back(std::max(peak, std::numeric_limits<double>::min()));
      weight_.push_back(c.weight ? *c.weight : 1.0 / scale_.back());
    }
    SetWindowEnd(config.window_end_s);
  }

  // Fits the part of the window up to `end_s` (continuation over the window length); gains,
  // offsets, scales and weights keep their meaning.
  void SetWindowEnd(double end_s) {
    end_ = std::min(full_end_, record_.WindowRange(config_.window_start_s, end_s).second);
    measured_.clear();
    for (const auto& c : config_.channels) {
      Eigen::VectorXd y(samples());
      for (int k = 0; k < samples(); ++k) y(k) = record_.values[c.record_channel][begin_ + k];
      measured_.push_back(std::move(y));
    }
  }

  // When the response starts: the first time any channel leaves its initial level by a fifth of
  // its largest excursion in the window.
  double OnsetTime() const {
    double onset = record_.time_s[full_end_ - 1];
    for (const auto& c : config_.channels) {
      const auto& y = record_.values[c.record_channel];
      const double initial = y[begin_];
      double excursion = 0.0;
      for (int k = begin_; k < full_end_; ++k) excursion = std::max(excursion, std::abs(y[k] - initial));
      for (int k = begin_; k < full_end_; ++k) {
        if (std::abs(y[k] - initial) > 0.2 * excursion) {
          onset = std::min(onset, record_.time_s[k]);
          break;
        }
      }
    }
    return onset;
  }

  int parameters() const { return static_cast<int>(config_.free.size()); }
  int channels() const { return static_cast<int>(config_.channels.size()); }
  int size() const { return parameters() + 2 * channels(); }
  int gain_index(int c) const { return parameters() + 2 * c; }
  int offset_index(int c) const { return parameters() + 2 * c + 1; }
  int samples() const { return end_ - begin_; }
  int residuals() const { return samples() * channels(); }
  int begin() const { return begin_; }
  const FitConfig& config() const { return config_; }
  double scale(int c) const { return scale_[c]; }
  double weight(int c) const { return weight_[c]; }
  void set_weight(int c, double w) { weight_[c] = w; }
  const Eigen::VectorXd& measured(int c) const { return measured_[c]; }
  long simulations() const { return simulations_; }

  double Physical(int i, double u) const {
    const auto& p = config_.free[i];
    return p.lower + u * (p.upper - p.lower);
  }
  double Normalised(int i, double value) const {
    const auto& p = config_.free[i];
    return (value - p.lower) / (p.upper - p.lower);
  }

  bool Torques(const double* theta, std::vector<Eigen::VectorXd>* m) const {
    driveline::Scene scene = scene_;
    for (int i = 0; i < parameters(); ++i) {
      config_.free[i].parameter.Set(Physical(i, theta[i]), &scene);
    }
    ++simulations_;
    std::string why;
    if (!SimulateChannels(scene, record_, config_.channels, begin_, end_, m, &why)) {
      last_failure_ = why;
      return false;
    }
    return true;
  }
  const std::string& last_failure() const { return last_failure_; }

  // Weighted residuals of channel c for torques m and the channel's gain and offset.
  void Residuals(const std::vector<Eigen::VectorXd>& m, const double* theta, double* r) const {
    for (int c = 0; c < channels(); ++c) {
      const double g = theta[gain_index(c)];
      const double o = theta[offset_index(c)] * scale_[c];
      Eigen::Map<Eigen::VectorXd>(r + c * samples(), samples()) =
          weight_[c] * (g * m[c].array() + o - measured_[c].array()).matrix();
    }
  }

  // Gains and offsets that minimise the residual for fixed torques m (linear least squares).
  void SolveNuisance(const std::vector<Eigen::VectorXd>& m, double* theta) const {
    for (int c = 0; c < channels(); ++c) {
      const auto& spec = config_.channels[c];
      const auto& y = measured_[c];
      double& g = theta[gain_index(c)];
      double& o = theta[offset_index(c)];
      const double n = static_cast<double>(samples());
      if (spec.fit_gain && spec.fit_offset) {
        const double mm = m[c].mean();
        const double ym = y.mean();
        const double sxx = (m[c].array() - mm).square().sum();
        const double sxy = ((m[c].array() - mm) * (y.array() - ym)).sum();
        g = sxx > 0.0 ? sxy / sxx : 1.0;
        o = (ym - g * mm) / scale_[c];
      } else if (spec.fit_gain) {
        const double mm2 = m[c].squaredNorm();
        g = mm2 > 0.0 ? (m[c].dot(y) - o * scale_[c] * m[c].sum()) / mm2 : 1.0;
      } else if (spec.fit_offset) {
        o = (y - g * m[c]).sum() / n / scale_[c];
      }
    }
  }

 private:
  const driveline::Scene& scene_;
  const Oscillogram& record_;
  const FitConfig& config_;
  int begin_ = 0;
  int end_ = 0;
  int full_end_ = 0;
  std::vector<double> scale_;
  std::vector<double> weight_;
  std::vector<Eigen::VectorXd> measured_;
  mutable long simulations_ = 0;
  mutable std::string last_failure_;
};

// The whole record misfit as one Ceres residual block over θ. Jacobian: central differences of
// the exact solution for the scene parameters, analytic for gains and offsets.
class RecordResidual : public ceres::CostFunction {
 public:
  // central: central differences (2 simulations per parameter, error ~ roundoff/step + step²),
  // else forward differences (1 simulation, error ~ step): enough to steer Levenberg–Marquardt,
  // whose answer depends on the residual, not the Jacobian's last digits.
  // transformed: the scene parameters enter as φ with u = (1 + sin φ)/2, which keeps u in [0, 1]
  // without Ceres bounds (bounds make Ceres run a projected line search that evaluates the full
  // Jacobian at every trial step: 10× the simulations); else as u itself (for the covariance).
  RecordResidual(const FitModel& model, double step, bool central, bool transformed = false)
      : model_(model), step_(step), central_(central), transformed_(transformed) {
    set_num_residuals(model.residuals());
    mutable_parameter_block_sizes()->push_back(model.size());
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    std::vector<double> u(parameters[0], parameters[0] + model_.size());
    if (transformed_) {
      for (int i = 0; i < model_.parameters(); ++i) u[i] = 0.5 * (1.0 + std::sin(u[i]));
    }
    const double* theta = u.data();
    std::vector<Eigen::VectorXd> m;
    if (!model_.Torques(theta, &m)) return false;
    model_.Residuals(m, theta, residuals);
    if (jacobians == nullptr || jacobians[0] == nullptr) return true;
    const int n = model_.samples();
    const int size = model_.size();
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
        jacobians[0], model_.residuals(), size);
    jac.setZero();
    for (int c = 0; c < model_.channels(); ++c) {
      const double w = model_.weight(c);
      jac.block(c * n, model_.gain_index(c), n, 1) = w * m[c];
      jac.block(c * n, model_.offset_index(c), n, 1).setConstant(w * model_.scale(c));
    }
    std::vector<double> probe(theta, theta + size);
    std::vector<Eigen::VectorXd> m1, m2;
    for (int i = 0; i < model_.parameters(); ++i) {
      const double u = theta[i];
      double h = step_;
      // Central where both neighbours are inside [0, 1]; second-order one-sided at a bound.
      int kind = 0;  // 0 central, +1 forward, −1 backward
      if (u - h < 0.0) kind = +1;
      else if (u + h > 1.0) kind = -1;
      Eigen::VectorXd derivative;
      if (!central_) {
        // A probe the solver cannot run (a rare event configuration it rejects) is retried on
        // the other side before the evaluation is declared failed.
        double signed_step = u + h > 1.0 ? -h : h;
        probe[i] = u + signed_step;
        if (!model_.Torques(probe.data(), &m1)) {
          signed_step = -signed_step;
          probe[i] = u + signed_step;
          if (signed_step + u < 0.0 || signed_step + u > 1.0 ||
              !model_.Torques(probe.data(), &m1)) {
            return false;
          }
        }
        probe[i] = u;
        for (int c = 0; c < model_.channels(); ++c) {
          jac.block(c * n, i, n, 1) = model_.weight(c) * theta[model_.gain_index(c)] *
                                      (m1[c] - m[c]) / signed_step;
        }
        if (transformed_) jac.col(i) *= 0.5 * std::cos(parameters[0][i]);
        continue;
      }
      // Central where both neighbours are inside [0, 1] and simulate; else second-order
      // one-sided on the side that does.
      bool done = false;
      if (kind == 0) {
        probe[i] = u + h;
        const bool up = model_.Torques(probe.data(), &m1);
        probe[i] = u - h;
        const bool down = up && model_.Torques(probe.data(), &m2);
        done = up && down;
        if (!done) kind = up ? +1 : -1;
      }
      if (!done) {
        if (u + 2 * kind * h < 0.0 || u + 2 * kind * h > 1.0) return false;
        probe[i] = u + kind * h;
        if (!model_.Torques(probe.data(), &m1)) return false;
        probe[i] = u + 2 * kind * h;
        if (!model_.Torques(probe.data(), &m2)) return false;
      }
      probe[i] = u;
      for (int c = 0; c < model_.channels(); ++c) {
        if (kind == 0) {
          derivative = (m1[c] - m2[c]) / (2.0 * h);
        } else {
          derivative = kind * (4.0 * m1[c] - 3.0 * m[c] - m2[c]) / (2.0 * h);
        }
        jac.block(c * n, i, n, 1) =
            model_.weight(c) * theta[model_.gain_index(c)] * derivative;
      }
      if (transformed_) jac.col(i) *= 0.5 * std::cos(parameters[0][i]);
    }
    return true;
  }

 private:
  const FitModel& model_;
  double step_;
  bool central_;
  bool transformed_;
};

struct LocalFit {
  std::vector<double> theta;
  double cost = std::numeric_limits<double>::infinity();
  ceres::Solver::Summary summary;
  bool usable = false;
};

std::vector<int> ConstantIndices(const FitModel& model) {
  std::vector<int> constant;
  for (int c = 0; c < model.channels(); ++c) {
    if (!model.config().channels[c].fit_gain) constant.push_back(model.gain_index(c));
    if (!model.config().channels[c].fit_offset) constant.push_back(model.offset_index(c));
  }
  return constant;
}

void SetUpProblem(const FitModel& model, RecordResidual* residual, std::vector<double>* theta,
                  ceres::Problem* problem) {
  problem->AddResidualBlock(residual, nullptr, theta->data());
  const auto constant = ConstantIndices(model);
  if (!constant.empty()) {
    problem->SetManifold(theta->data(), new ceres::SubsetManifold(model.size(), constant));
  }
}

ceres::Problem::Options ProblemOptions() {
  ceres::Problem::Options options;
  options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return options;
}

// A continuation stage (`final_stage` false) stops at a loose tolerance: its answer only has to
// start the next stage inside the right basin.
LocalFit Refine(const FitModel& model, const FitOptions& options, std::vector<double> theta,
                bool final_stage) {
  RecordResidual residual(model, options.derivative_step, options.central_differences,
                          /*transformed=*/true);
  ceres::Problem problem(ProblemOptions());
  LocalFit fit;
  fit.theta = std::move(theta);
  for (int i = 0; i < model.parameters(); ++i) {
    fit.theta[i] = std::asin(std::clamp(2.0 * fit.theta[i] - 1.0, -1.0, 1.0));
  }
  SetUpProblem(model, &residual, &fit.theta, &problem);
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = final_stage ? options.max_iterations : kStageIterations;
  solver.function_tolerance = final_stage ? 1e-15 : 1e-6;
  solver.parameter_tolerance = final_stage ? 1e-12 : 1e-6;
  solver.gradient_tolerance = 1e-20;
  solver.num_threads = options.threads;
  solver.logging_type = ceres::SILENT;
  ceres::Solve(solver, &problem, &fit.summary);
  for (int i = 0; i < model.parameters(); ++i) fit.theta[i] = 0.5 * (1.0 + std::sin(fit.theta[i]));
  fit.usable = fit.summary.IsSolutionUsable() && std::isfinite(fit.summary.final_cost);
  fit.cost = fit.usable ? fit.summary.final_cost : std::numeric_limits<double>::infinity();
  if (!fit.usable && fit.summary.termination_type == ceres::FAILURE) {
    // Ceres stops when the Jacobian cannot be evaluated at an accepted point (a simulation the
    // solver rejects at a finite-difference probe). The accepted point itself is a valid,
    // improved answer; the next stage or the polish carries on from it.
    std::vector<Eigen::VectorXd> m;
    if (model.Torques(fit.theta.data(), &m)) {
      Eigen::VectorXd r(model.residuals());
      model.Residuals(m, fit.theta.data(), r.data());
      fit.cost = 0.5 * r.squaredNorm();
      fit.usable = std::isfinite(fit.cost);
    }
  }
  return fit;
}

// Coarse scan: the start point, then a Latin hypercube over the scanned parameters (others at
// their start), each with gains and offsets solved linearly. Returns θ of the `starts` best.
std::vector<std::vector<double>> ScanStarts(const FitModel& model, const FitConfig& config,
                                            std::vector<double> start, int* evaluated) {
  std::vector<int> scanned;
  for (int i = 0; i < model.parameters(); ++i) {
    if (config.free[i].scan) scanned.push_back(i);
  }
  const int points = scanned.empty() ? 0 : config.scan_points;
  std::mt19937_64 random(config.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<std::vector<double>> lattice(scanned.size(), std::vector<double>(points));
  for (auto& column : lattice) {
    for (int k = 0; k < points; ++k) column[k] = (k + uniform(random)) / points;
    std::shuffle(column.begin(), column.end(), random);
  }
  std::vector<std::pair<double, std::vector<double>>> candidates;
  std::vector<Eigen::VectorXd> m;
  Eigen::VectorXd r(model.residuals());
  for (int k = -1; k < points; ++k) {
    std::vector<double> theta = start;
    if (k >= 0) {
      for (size_t s = 0; s < scanned.size(); ++s) theta[scanned[s]] = lattice[s][k];
    }
    if (!model.Torques(theta.data(), &m)) continue;
    model.SolveNuisance(m, theta.data());
    model.Residuals(m, theta.data(), r.data());
    candidates.emplace_back(0.5 * r.squaredNorm(), theta);
  }
  *evaluated = points;
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::vector<double>> best;
  for (int k = 0; k < std::min<int>(config.starts, static_cast<int>(candidates.size())); ++k) {
    best.push_back(candidates[k].second);
  }
  return best;
}

std::string Short(double value) {
  std::ostringstream out;
  out << std::setprecision(3) << value;
  return out.str();
}

// Identifiability, three tests on the noise-weighted Jacobian (columns over θ, scene parameters
// first, in units of their bound width):
//  - sensitivity: even if every other quantity were known, the standard error noise/‖column‖
//    exceeds kUnidentifiableFraction of the bound width (the record hardly depends on it; this
//    catches what a truncated-SVD covariance would report with a tiny standard error);
//  - collinearity: the column-scaled Jacobian has a singular value below kRankTolerance of the
//    largest whose singular vector involves the parameter;
//  - the full standard error exceeds kUnidentifiableFraction of the bound width.
void FlagUnidentifiable(const Eigen::MatrixXd& jac, const std::vector<int>& fitted,
                        double noise_scale, FitResult* result) {
  const int p = static_cast<int>(result->parameters.size());
  Eigen::MatrixXd scaled(jac.rows(), fitted.size());
  std::vector<double> norms(fitted.size());
  for (size_t j = 0; j < fitted.size(); ++j) {
    norms[j] = jac.col(fitted[j]).norm();
    scaled.col(j) = norms[j] > 0.0 ? Eigen::VectorXd(jac.col(fitted[j]) / norms[j])
                                   : Eigen::VectorXd(jac.col(fitted[j]));
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled, Eigen::ComputeThinV);
  const auto& sv = svd.singularValues();
  result->summary.reciprocal_condition =
      sv.size() > 0 && sv(0) > 0.0 ? sv(sv.size() - 1) / sv(0) : 0.0;
  for (size_t j = 0; j < fitted.size(); ++j) {
    if (fitted[j] >= p) continue;  // gains and offsets are reported, not flagged
    auto& estimate = result->parameters[fitted[j]];
    const double width = estimate.upper - estimate.lower;
    const double limit = kUnidentifiableFraction * width;
    const double alone = norms[j] > 0.0 ? noise_scale / norms[j] * width
                                        : std::numeric_limits<double>::infinity();
    if (!(alone <= limit)) {
      estimate.identifiable = false;
      estimate.why_not = "the record hardly depends on it: even with every other quantity known "
                         "its standard error would be " + Short(alone) + ", more than " +
                         Short(kUnidentifiableFraction) + " of its bound width " +
                         Short(width);
      continue;
    }
    for (int k = 0; k < sv.size(); ++k) {
      if (sv(k) < kRankTolerance * sv(0) && std::abs(svd.matrixV()(j, k)) > 0.1) {
        estimate.identifiable = false;
        estimate.why_not = "the Jacobian is rank-deficient in its direction (singular value " +
                           Short(sv(k) / sv(0)) + " of the largest): it trades off " +
                           "against other parameters";
      }
    }
    if (estimate.identifiable && !(estimate.standard_error <= limit)) {
      estimate.identifiable = false;
      estimate.why_not = "its standard error " + Short(estimate.standard_error) +
                         " exceeds " + Short(kUnidentifiableFraction) +
                         " of its bound width " + Short(width);
    }
  }
}

}  // namespace

std::vector<double> CramerRaoBound(const driveline::Scene& scene, const Oscillogram& record,
                                   const FitConfig& config, const std::vector<double>& noise_Nm,
                                   const FitOptions& options) {
  options.Validate();
  ValidateFitConfig(config, record, "fit config");
  FitModel model(scene, record, config);
  std::vector<double> theta(model.size(), 0.0);
  for (int i = 0; i < model.parameters(); ++i) {
    theta[i] = model.Normalised(i, config.free[i].parameter.Get(scene));
  }
  for (int c = 0; c < model.channels(); ++c) {
    theta[model.gain_index(c)] = 1.0;
    model.set_weight(c, 1.0 / noise_Nm.at(c));
  }
  RecordResidual residual(model, options.derivative_step, /*central=*/true);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jac(model.residuals(),
                                                                              model.size());
  Eigen::VectorXd r(model.residuals());
  const double* parameters[] = {theta.data()};
  double* jacobians[] = {jac.data()};
  if (!residual.Evaluate(parameters, r.data(), jacobians)) {
    throw InputError("Cramér–Rao bound: the scene does not simulate: " + model.last_failure());
  }
  std::vector<int> fitted;
  const auto constant = ConstantIndices(model);
  for (int j = 0; j < model.size(); ++j) {
    if (std::find(constant.begin(), constant.end(), j) == constant.end()) fitted.push_back(j);
  }
  Eigen::MatrixXd reduced(jac.rows(), fitted.size());
  for (size_t j = 0; j < fitted.size(); ++j) reduced.col(j) = jac.col(fitted[j]);
  const Eigen::MatrixXd information = reduced.transpose() * reduced;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(information);
  const Eigen::MatrixXd inverse =
      ldlt.solve(Eigen::MatrixXd::Identity(information.rows(), information.cols()));
  std::vector<double> bound;
  for (int i = 0; i < model.parameters(); ++i) {
    const auto& free = config.free[i];
    const double variance = inverse(i, i);
    bound.push_back(variance > 0.0 && std::isfinite(variance)
                        ? std::sqrt(variance) * (free.upper - free.lower)
                        : std::numeric_limits<double>::quiet_NaN());
  }
  return bound;
}

FitResult Fit(const driveline::Scene& scene, const Oscillogram& record, const FitConfig& config,
              const FitOptions& options) {
  options.Validate();
  ValidateFitConfig(config, record, "fit config");
  const auto clock_start = std::chrono::steady_clock::now();
  FitModel model(scene, record, config);
  FitResult result;
  auto& summary = result.summary;

  // Continuation over the window length: the first stage ends shortly after the response starts,
  // where impact timing (gaps, bite time) dominates and the misfit has few local minima; each
  // stage doubles the fitted span and starts from the previous stage's answer.
  std::vector<double> stage_ends;
  {
    const double onset = model.OnsetTime();
    const double span = config.window_end_s - onset;
    for (int j = kContinuationStages - 1; j >= 1; --j) {
      const double end = onset + span / static_cast<double>(1 << j);
      const auto [first, last] = record.WindowRange(config.window_start_s, end);
      if (last - first >= kMinRecordSamples) stage_ends.push_back(end);
    }
    stage_ends.push_back(config.window_end_s);
  }
  model.SetWindowEnd(stage_ends.front());

  std::vector<double> start(model.size(), 0.0);
  for (int i = 0; i < model.parameters(); ++i) start[i] = model.Normalised(i, config.free[i].start);
  for (int c = 0; c < model.channels(); ++c) start[model.gain_index(c)] = 1.0;
  {
    std::vector<Eigen::VectorXd> m;
    if (!model.Torques(start.data(), &m)) {
      summary.message = "the start point does not simulate: " + model.last_failure();
      return result;
    }
    model.SolveNuisance(m, start.data());
    // Only the fitted nuisance values move from their defaults.
    for (int c = 0; c < model.channels(); ++c) {
      if (!config.channels[c].fit_gain) start[model.gain_index(c)] = 1.0;
      if (!config.channels[c].fit_offset) start[model.offset_index(c)] = 0.0;
    }
  }
  const auto starts = ScanStarts(model, config, start, &summary.scan_points);

  LocalFit best;
  for (const auto& theta : starts) {
    LocalFit fit;
    fit.theta = theta;
    for (const double end : stage_ends) {
      model.SetWindowEnd(end);
      LocalFit stage = Refine(model, options, fit.theta, end == stage_ends.back());
      if (!stage.usable) {
        fit = std::move(stage);
        break;
      }
      fit = std::move(stage);
    }
    model.SetWindowEnd(stage_ends.front());
    LocalMinimum minimum;
    minimum.cost = fit.cost;
    minimum.iterations = static_cast<int>(fit.summary.iterations.size());
    minimum.converged = fit.summary.termination_type == ceres::CONVERGENCE;
    for (int i = 0; i < model.parameters(); ++i) {
      minimum.values.push_back(model.Physical(i, fit.theta[i]));
    }
    result.minima.push_back(minimum);
    if (fit.cost < best.cost) best = std::move(fit);
  }
  model.SetWindowEnd(config.window_end_s);
  summary.starts = static_cast<int>(starts.size());
  if (!best.usable) {
    summary.message = "no start converged to a usable solution";
    if (!model.last_failure().empty()) summary.message += " (last failure: " + model.last_failure() + ")";
    summary.simulations = model.simulations();
    return result;
  }
  for (const auto& minimum : result.minima) {
    if (minimum.cost <= best.cost * (1.0 + 1e-6) + std::numeric_limits<double>::min()) {
      ++summary.starts_at_best;
    }
  }

  // Noise weights for the channels without a user weight, then a polish with them.
  const int n = model.samples();
  const int fitted_count = model.size() - static_cast<int>(ConstantIndices(model).size());
  const double dof = static_cast<double>(model.residuals() - fitted_count);
  if (dof <= 0.0) {
    summary.message = "more fitted quantities than samples in the window";
    return result;
  }
  std::vector<Eigen::VectorXd> m;
  Eigen::VectorXd r(model.residuals());
  if (options.polish_with_noise_weights) {
    bool reweighted = false;
    model.Torques(best.theta.data(), &m);
    model.Residuals(m, best.theta.data(), r.data());
    for (int c = 0; c < model.channels(); ++c) {
      if (config.channels[c].weight) continue;
      const double rms = r.segment(c * n, n).norm() / model.weight(c) / std::sqrt(n);
      const double noise = std::max(rms * std::sqrt(model.residuals() / dof), 1e-13 * model.scale(c));
      model.set_weight(c, 1.0 / noise);
      reweighted = true;
    }
    if (reweighted) {
      LocalFit polished = Refine(model, options, best.theta, /*final_stage=*/true);
      if (polished.usable) best = std::move(polished);
    }
  }

  // Final residuals, Jacobian and covariance.
  RecordResidual residual(model, options.derivative_step, /*central=*/true);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jac(model.residuals(),
                                                                              model.size());
  {
    const double* parameters[] = {best.theta.data()};
    double* jacobians[] = {jac.data()};
    if (!residual.Evaluate(parameters, r.data(), jacobians)) {
      summary.message = "the solution does not simulate: " + model.last_failure();
      return result;
    }
  }
  summary.cost = 0.5 * r.squaredNorm();
  summary.residuals = model.residuals();
  summary.fitted_quantities = fitted_count;
  summary.noise_scale = std::sqrt(2.0 * summary.cost / dof);

  Eigen::MatrixXd covariance = Eigen::MatrixXd::Zero(model.size(), model.size());
  {
    ceres::Problem problem(ProblemOptions());
    std::vector<double> theta = best.theta;
    SetUpProblem(model, &residual, &theta, &problem);
    ceres::Covariance::Options covariance_options;
    covariance_options.algorithm_type = ceres::DENSE_SVD;
    covariance_options.null_space_rank = -1;
    covariance_options.min_reciprocal_condition_number = 1e-14;
    ceres::Covariance ceres_covariance(covariance_options);
    const std::vector<std::pair<const double*, const double*>> blocks = {
        {theta.data(), theta.data()}};
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c(model.size(),
                                                                            model.size());
    if (ceres_covariance.Compute(blocks, &problem) &&
        ceres_covariance.GetCovarianceMatrix({theta.data()}, c.data())) {
      covariance = c * (summary.noise_scale * summary.noise_scale);
    } else {
      covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
    }
  }

  std::vector<int> fitted;
  const auto constant = ConstantIndices(model);
  for (int j = 0; j < model.size(); ++j) {
    if (std::find(constant.begin(), constant.end(), j) == constant.end()) fitted.push_back(j);
  }
  for (int i = 0; i < model.parameters(); ++i) {
    const auto& free = config.free[i];
    ParameterEstimate e;
    e.name = free.parameter.name;
    e.unit = free.parameter.unit;
    e.value = model.Physical(i, best.theta[i]);
    e.standard_error = std::sqrt(covariance(i, i)) * (free.upper - free.lower);
    e.start = free.start;
    e.lower = free.lower;
    e.upper = free.upper;
    e.at_bound = best.theta[i] <= 0.0 || best.theta[i] >= 1.0;
    result.parameters.push_back(e);
  }
  FlagUnidentifiable(jac, fitted, summary.noise_scale, &result);

  model.Torques(best.theta.data(), &m);
  for (int c = 0; c < model.channels(); ++c) {
    ChannelEstimate e;
    e.column = config.channels[c].column;
    e.link = config.channels[c].link;
    e.gain = best.theta[model.gain_index(c)];
    e.gain_se = std::sqrt(covariance(model.gain_index(c), model.gain_index(c)));
    e.offset = best.theta[model.offset_index(c)] * model.scale(c);
    e.offset_se = std::sqrt(covariance(model.offset_index(c), model.offset_index(c))) * model.scale(c);
    e.weight = model.weight(c);
    e.samples = n;
    const Eigen::VectorXd fitted_trace = e.gain * m[c].array() + e.offset;
    e.fitted.assign(fitted_trace.data(), fitted_trace.data() + n);
    e.measured.assign(model.measured(c).data(), model.measured(c).data() + n);
    e.rms_residual = (fitted_trace - model.measured(c)).norm() / std::sqrt(n);
    result.channels.push_back(e);
  }
  for (int k = 0; k < n; ++k) result.window_time_s.push_back(record.time_s[model.begin() + k]);

  for (int j : fitted) {
    if (j < model.parameters()) {
      result.quantity_names.push_back(config.free[j].parameter.name);
    } else {
      const int c = (j - model.parameters()) / 2;
      const bool gain = j == model.gain_index(c);
      result.quantity_names.push_back((gain ? "gain." : "offset.") + config.channels[c].column);
    }
  }
  result.correlation.resize(fitted.size(), fitted.size());
  for (size_t a = 0; a < fitted.size(); ++a) {
    for (size_t b = 0; b < fitted.size(); ++b) {
      result.correlation(a, b) = covariance(fitted[a], fitted[b]) /
                                 std::sqrt(covariance(fitted[a], fitted[a]) *
                                           covariance(fitted[b], fitted[b]));
    }
  }

  summary.success = true;
  summary.ceres_brief = best.summary.BriefReport();
  summary.termination = ceres::TerminationTypeToString(best.summary.termination_type);
  summary.iterations = static_cast<int>(best.summary.iterations.size());
  summary.simulations = model.simulations();
  summary.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

}  // namespace millkit::identify
