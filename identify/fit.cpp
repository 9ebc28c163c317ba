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

// The fitted quantities over R records (one simulation of the scene per record):
//   θ = [u_1 … u_S, g_1, ô_1, …, g_B, ô_B].
// Slot s is a free parameter, shared by every record or, for a per-record parameter (bite time),
// one copy per record; u_s = (p_s − lower)/(upper − lower) in [0, 1]. Block b is one channel of
// one record, with its own gain g_b and offset ô_b = o_b / S_b (S_b the block's peak |y|).
// Residuals are the blocks' samples in the current window, block after block.
class FitModel {
 public:
  struct Slot {
    int free = 0;     // index in config.free
    int record = -1;  // −1: shared by every record
    std::string name;
  };
  struct Block {
    int record = 0;
    int channel = 0;  // index in config.channels
    int column = 0;   // index in the record's channels
    int begin = 0;    // window samples [begin, end) of the record
    int end = 0;
    int full_end = 0;
    double scale = 1.0;
    double weight = 1.0;
    Eigen::VectorXd measured;
    int offset = 0;   // first residual of the block
  };

  FitModel(const driveline::Scene& scene, const std::vector<Oscillogram>& records,
           const FitConfig& config)
      : scene_(scene), records_(records), config_(config) {
    const int record_count = static_cast<int>(records.size());
    labels_ = RecordLabels(records);
    for (int i = 0; i < static_cast<int>(config.free.size()); ++i) {
      const auto& name = config.free[i].parameter.name;
      if (config.free[i].per_record && record_count > 1) {
        for (int r = 0; r < record_count; ++r) slots_.push_back({i, r, name + "@" + labels_[r]});
      } else {
        slots_.push_back({i, -1, name});
      }
    }
    for (int r = 0; r < record_count; ++r) {
      const auto& record = records[r];
      const auto [begin, end] = record.WindowRange(config.window_start_s, config.window_end_s);
      for (int c = 0; c < static_cast<int>(config.channels.size()); ++c) {
        Block b;
        b.record = r;
        b.channel = c;
        b.column = record.ChannelIndex(config.channels[c].column);
        b.begin = begin;
        b.end = b.full_end = end;
        double peak = 0.0;
        for (int k = begin; k < end; ++k) peak = std::max(peak, std::abs(record.values[b.column][k]));
        b.scale = std::max(peak, std::numeric_limits<double>::min());
        b.weight = config.channels[c].weight ? *config.channels[c].weight : 1.0 / b.scale;
        blocks_.push_back(std::move(b));
      }
      onsets_.push_back(OnsetTime(r));
    }
    SetStage(1.0);
  }

  // Continuation over the window length: each record's window ends at onset + (end − onset)/d
  // (d = 1: the whole window); gains, offsets, scales and weights keep their meaning.
  void SetStage(double divisor) {
    int offset = 0;
    for (auto& b : blocks_) {
      const auto& record = records_[b.record];
      b.end = StageEnd(b, divisor);
      b.measured = Eigen::Map<const Eigen::VectorXd>(record.values[b.column].data() + b.begin,
                                                     b.end - b.begin);
      b.offset = offset;
      offset += b.end - b.begin;
    }
    residuals_ = offset;
  }
  // The fewest window samples of any block at this stage.
  int FewestSamples(double divisor) const {
    int fewest = std::numeric_limits<int>::max();
    for (const auto& b : blocks_) fewest = std::min(fewest, StageEnd(b, divisor) - b.begin);
    return fewest;
  }

  int parameters() const { return static_cast<int>(slots_.size()); }
  int blocks() const { return static_cast<int>(blocks_.size()); }
  int size() const { return parameters() + 2 * blocks(); }
  int gain_index(int b) const { return parameters() + 2 * b; }
  int offset_index(int b) const { return parameters() + 2 * b + 1; }
  int residuals() const { return residuals_; }
  const Block& block(int b) const { return blocks_[b]; }
  const Slot& slot(int s) const { return slots_[s]; }
  const FreeParameter& free(int s) const { return config_.free[slots_[s].free]; }
  const ChannelSpec& channel_spec(int b) const { return config_.channels[blocks_[b].channel]; }
  const Oscillogram& record(int r) const { return records_[r]; }
  void set_weight(int b, double w) { blocks_[b].weight = w; }
  long simulations() const { return simulations_; }

  double Physical(int s, double u) const {
    const auto& p = free(s);
    return p.lower + u * (p.upper - p.lower);
  }
  double Normalised(int s, double value) const {
    const auto& p = free(s);
    return (value - p.lower) / (p.upper - p.lower);
  }

  // Simulated link torque of every block (m[b]); with `only_record` ≥ 0 only that record's
  // blocks are simulated (the others are left as they are).
  bool Torques(const double* theta, std::vector<Eigen::VectorXd>* m, int only_record = -1) const {
    m->resize(blocks_.size());
    std::vector<Eigen::VectorXd> torques;
    for (int r = 0; r < static_cast<int>(records_.size()); ++r) {
      if (only_record >= 0 && r != only_record) continue;
      driveline::Scene scene = scene_;
      for (int s = 0; s < parameters(); ++s) {
        if (slots_[s].record < 0 || slots_[s].record == r) {
          free(s).parameter.Set(Physical(s, theta[s]), &scene);
        }
      }
      // Blocks of a record are consecutive, in config channel order.
      const Block& first = blocks_[r * config_.channels.size()];
      ++simulations_;
      std::string why;
      if (!SimulateChannels(scene, records_[r], config_.channels, first.begin, first.end,
                            &torques, &why)) {
        last_failure_ = records_.size() > 1 ? records_[r].source + ": " + why : why;
        return false;
      }
      for (size_t c = 0; c < torques.size(); ++c) {
        (*m)[r * config_.channels.size() + c] = std::move(torques[c]);
      }
    }
    return true;
  }
  const std::string& last_failure() const { return last_failure_; }

  // Weighted residuals g_b m_b + o_b − y_b of every block.
  void Residuals(const std::vector<Eigen::VectorXd>& m, const double* theta, double* r) const {
    for (int b = 0; b < blocks(); ++b) {
      const auto& block = blocks_[b];
      const double g = theta[gain_index(b)];
      const double o = theta[offset_index(b)] * block.scale;
      Eigen::Map<Eigen::VectorXd>(r + block.offset, block.measured.size()) =
          block.weight * (g * m[b].array() + o - block.measured.array()).matrix();
    }
  }

  // Gains and offsets that minimise the residual for fixed torques m (linear least squares).
  void SolveNuisance(const std::vector<Eigen::VectorXd>& m, double* theta) const {
    for (int b = 0; b < blocks(); ++b) {
      const auto& spec = channel_spec(b);
      const auto& y = blocks_[b].measured;
      const auto& x = m[b];
      const double scale = blocks_[b].scale;
      double& g = theta[gain_index(b)];
      double& o = theta[offset_index(b)];
      const double n = static_cast<double>(y.size());
      if (spec.fit_gain && spec.fit_offset) {
        const double mm = x.mean();
        const double ym = y.mean();
        const double sxx = (x.array() - mm).square().sum();
        const double sxy = ((x.array() - mm) * (y.array() - ym)).sum();
        g = sxx > 0.0 ? sxy / sxx : 1.0;
        o = (ym - g * mm) / scale;
      } else if (spec.fit_gain) {
        const double mm2 = x.squaredNorm();
        g = mm2 > 0.0 ? (x.dot(y) - o * scale * x.sum()) / mm2 : 1.0;
      } else if (spec.fit_offset) {
        o = (y - g * x).sum() / n / scale;
      }
    }
  }

  // Name of block b's gain or offset: gain.<column>, with @<record> when there are several.
  std::string NuisanceName(int b, bool gain) const {
    std::string name = (gain ? "gain." : "offset.") + channel_spec(b).column;
    if (records_.size() > 1) name += "@" + labels_[blocks_[b].record];
    return name;
  }
  // RecordLabels() of the records.
  const std::string& label(int r) const { return labels_[r]; }

 private:
  // Block b's window end (sample index) at the stage with this divisor.
  int StageEnd(const Block& b, double divisor) const {
    if (divisor == 1.0) return b.full_end;
    const double onset = onsets_[b.record];
    const double end_s = onset + (config_.window_end_s - onset) / divisor;
    return std::min(b.full_end,
                    records_[b.record].WindowRange(config_.window_start_s, end_s).second);
  }

  // When record r's response starts: the first time any channel leaves its initial level by a
  // fifth of its largest excursion in the window.
  double OnsetTime(int r) const {
    const auto& record = records_[r];
    double onset = record.time_s[blocks_.back().full_end - 1];
    for (const auto& b : blocks_) {
      if (b.record != r) continue;
      const auto& y = record.values[b.column];
      const double initial = y[b.begin];
      double excursion = 0.0;
      for (int k = b.begin; k < b.full_end; ++k) excursion = std::max(excursion, std::abs(y[k] - initial));
      for (int k = b.begin; k < b.full_end; ++k) {
        if (std::abs(y[k] - initial) > 0.2 * excursion) {
          onset = std::min(onset, record.time_s[k]);
          break;
        }
      }
    }
    return onset;
  }

  const driveline::Scene& scene_;
  const std::vector<Oscillogram>& records_;
  const FitConfig& config_;
  std::vector<std::string> labels_;
  std::vector<Slot> slots_;
  std::vector<Block> blocks_;
  std::vector<double> onsets_;
  int residuals_ = 0;
  mutable long simulations_ = 0;
  mutable std::string last_failure_;
};

// The whole misfit as one Ceres residual block over θ. Jacobian: finite differences of the exact
// solution for the scene parameters (a per-record slot re-simulates only its record), analytic
// for gains and offsets.
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
    const int size = model_.size();
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
        jacobians[0], model_.residuals(), size);
    jac.setZero();
    for (int b = 0; b < model_.blocks(); ++b) {
      const auto& block = model_.block(b);
      const int n = static_cast<int>(block.measured.size());
      jac.block(block.offset, model_.gain_index(b), n, 1) = block.weight * m[b];
      jac.block(block.offset, model_.offset_index(b), n, 1).setConstant(block.weight * block.scale);
    }
    std::vector<double> probe(theta, theta + size);
    // A probe of a per-record slot simulates (and fills) only that record's blocks; `write`
    // reads no others.
    std::vector<Eigen::VectorXd> m1, m2;
    // Writes column i from the probes' torques: d = (weighted) derivative of block b.
    const auto write = [&](int i, const auto& derivative_of) {
      const int only = model_.slot(i).record;
      for (int b = 0; b < model_.blocks(); ++b) {
        const auto& block = model_.block(b);
        if (only >= 0 && block.record != only) continue;
        jac.block(block.offset, i, block.measured.size(), 1) =
            block.weight * theta[model_.gain_index(b)] * derivative_of(b);
      }
      if (transformed_) jac.col(i) *= 0.5 * std::cos(parameters[0][i]);
    };
    for (int i = 0; i < model_.parameters(); ++i) {
      if (std::find(frozen_.begin(), frozen_.end(), i) != frozen_.end()) continue;
      const int only = model_.slot(i).record;
      const double u0 = theta[i];
      const double h = step_;
      const auto simulate = [&](double value, std::vector<Eigen::VectorXd>* out) {
        probe[i] = value;
        const bool ok = model_.Torques(probe.data(), out, only);
        probe[i] = u0;
        return ok;
      };
      if (!central_) {
        // A probe the solver cannot run (a rare event configuration it rejects) is retried on
        // the other side before the evaluation is declared failed.
        double signed_step = u0 + h > 1.0 ? -h : h;
        if (!simulate(u0 + signed_step, &m1)) {
          signed_step = -signed_step;
          if (u0 + signed_step < 0.0 || u0 + signed_step > 1.0 || !simulate(u0 + signed_step, &m1)) {
            return false;
          }
        }
        write(i, [&](int b) { return Eigen::VectorXd((m1[b] - m[b]) / signed_step); });
        continue;
      }
      // Central where both neighbours are inside [0, 1] and simulate; else second-order
      // one-sided on the side that does.
      int kind = 0;  // 0 central, +1 forward, −1 backward
      if (u0 - h < 0.0) kind = +1;
      else if (u0 + h > 1.0) kind = -1;
      bool done = false;
      if (kind == 0) {
        const bool up = simulate(u0 + h, &m1);
        const bool down = up && simulate(u0 - h, &m2);
        done = up && down;
        if (!done) kind = up ? +1 : -1;
      }
      if (!done) {
        if (u0 + 2 * kind * h < 0.0 || u0 + 2 * kind * h > 1.0) return false;
        if (!simulate(u0 + kind * h, &m1) || !simulate(u0 + 2 * kind * h, &m2)) return false;
        write(i, [&](int b) {
          return Eigen::VectorXd(kind * (4.0 * m1[b] - 3.0 * m[b] - m2[b]) / (2.0 * h));
        });
      } else {
        write(i, [&](int b) { return Eigen::VectorXd((m1[b] - m2[b]) / (2.0 * h)); });
      }
    }
    return true;
  }

  // Held constant by the problem: their Jacobian columns are left zero, unsimulated.
  void Freeze(const std::vector<int>& slots) { frozen_ = slots; }

 private:
  std::vector<int> frozen_;
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
  for (int b = 0; b < model.blocks(); ++b) {
    if (!model.channel_spec(b).fit_gain) constant.push_back(model.gain_index(b));
    if (!model.channel_spec(b).fit_offset) constant.push_back(model.offset_index(b));
  }
  return constant;
}

void SetUpProblem(const FitModel& model, RecordResidual* residual, std::vector<double>* theta,
                  ceres::Problem* problem, const std::vector<int>& frozen = {}) {
  problem->AddResidualBlock(residual, nullptr, theta->data());
  auto constant = ConstantIndices(model);
  constant.insert(constant.end(), frozen.begin(), frozen.end());
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
                bool final_stage, int stage_iterations = kStageIterations,
                const std::vector<int>& frozen = {}) {
  RecordResidual residual(model, options.derivative_step, options.central_differences,
                          /*transformed=*/true);
  residual.Freeze(frozen);
  ceres::Problem problem(ProblemOptions());
  LocalFit fit;
  fit.theta = std::move(theta);
  for (int i = 0; i < model.parameters(); ++i) {
    fit.theta[i] = std::asin(std::clamp(2.0 * fit.theta[i] - 1.0, -1.0, 1.0));
  }
  SetUpProblem(model, &residual, &fit.theta, &problem, frozen);
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = final_stage ? options.max_iterations : stage_iterations;
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
    if (model.free(i).scan) scanned.push_back(i);
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
  const std::vector<Oscillogram> records = {record};
  ValidateFitConfig(config, records, "fit config");
  FitModel model(scene, records, config);
  std::vector<double> theta(model.size(), 0.0);
  for (int i = 0; i < model.parameters(); ++i) {
    theta[i] = model.Normalised(i, model.free(i).parameter.Get(scene));
  }
  for (int b = 0; b < model.blocks(); ++b) {
    theta[model.gain_index(b)] = 1.0;
    model.set_weight(b, 1.0 / noise_Nm.at(b));
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
    const auto& free = model.free(i);
    const double variance = inverse(i, i);
    bound.push_back(variance > 0.0 && std::isfinite(variance)
                        ? std::sqrt(variance) * (free.upper - free.lower)
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
  FitModel model(scene, records, config);
  FitResult result;
  auto& summary = result.summary;

  // Continuation over the window length: the first stage ends shortly after the response starts,
  // where impact timing (gaps, bite time) dominates and the misfit has few local minima; each
  // stage doubles the fitted span and starts from the previous stage's answer.
  std::vector<double> stages;  // window divisors, the last 1 (the whole window)
  for (int j = kContinuationStages - 1; j >= 1; --j) {
    const double divisor = static_cast<double>(1 << j);
    if (model.FewestSamples(divisor) >= kMinRecordSamples) stages.push_back(divisor);
  }
  stages.push_back(1.0);
  model.SetStage(stages.front());

  std::vector<double> start(model.size(), 0.0);
  for (int i = 0; i < model.parameters(); ++i) start[i] = model.Normalised(i, model.free(i).start);
  for (int b = 0; b < model.blocks(); ++b) start[model.gain_index(b)] = 1.0;
  {
    std::vector<Eigen::VectorXd> m;
    if (!model.Torques(start.data(), &m)) {
      summary.message = "the start point does not simulate: " + model.last_failure();
      return result;
    }
    model.SolveNuisance(m, start.data());
    // Only the fitted nuisance values move from their defaults.
    for (int b = 0; b < model.blocks(); ++b) {
      if (!model.channel_spec(b).fit_gain) start[model.gain_index(b)] = 1.0;
      if (!model.channel_spec(b).fit_offset) start[model.offset_index(b)] = 0.0;
    }
  }
  const auto starts = ScanStarts(model, config, start, &summary.scan_points);

  LocalFit best;
  const auto record_minimum = [&](LocalFit fit) {
    LocalMinimum minimum;
    minimum.cost = fit.cost;
    minimum.iterations = static_cast<int>(fit.summary.iterations.size());
    minimum.converged = fit.summary.termination_type == ceres::CONVERGENCE;
    for (int i = 0; i < model.parameters(); ++i) {
      minimum.values.push_back(model.Physical(i, fit.theta[i]));
    }
    result.minima.push_back(minimum);
    if (fit.cost < best.cost) best = std::move(fit);
  };
  // The first kTimingOnlyStages stages fit the scanned parameters (gaps, bite time: the impact
  // timing a short window sees) with gains and offsets; the others (dampings, stiffness), which a
  // short window hardly constrains, are held at their start there.
  std::vector<int> unscanned;
  for (int i = 0; i < model.parameters(); ++i) {
    if (!model.free(i).scan) unscanned.push_back(i);
  }
  if (static_cast<int>(unscanned.size()) == model.parameters()) unscanned.clear();
  for (const auto& theta : starts) {
    LocalFit fit;
    fit.theta = theta;
    int stage_number = 0;
    for (const double divisor : stages) {
      model.SetStage(divisor);
      LocalFit stage = Refine(model, options, fit.theta, divisor == 1.0, kStageIterations,
                              stage_number++ < kTimingOnlyStages ? unscanned : std::vector<int>{});
      if (!stage.usable) {
        fit = std::move(stage);
        break;
      }
      fit = std::move(stage);
    }
    const double continued_cost = fit.cost;
    record_minimum(std::move(fit));
    // The same start refined on the whole window at once. A short stage sees the dampings
    // poorly, and noise can carry them into the basin of a neighbouring minimum of the whole
    // window (a dead-zone re-entry that only just happens or not); a fit from a start inside the
    // right basin stays there. A capped try first: it is finished only when it comes near the
    // continued fit (from a poor start it usually wanders to a bound and is dropped).
    if (stages.size() > 1) {
      model.SetStage(1.0);
      LocalFit direct = Refine(model, options, theta, /*final_stage=*/false, kDirectTryIterations);
      if (direct.usable && direct.cost < kDirectRetryFactor * continued_cost) {
        direct = Refine(model, options, direct.theta, /*final_stage=*/true);
      }
      record_minimum(std::move(direct));
    }
  }
  model.SetStage(1.0);
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

  // Noise weights for the blocks without a user weight, then a polish with them.
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
    for (int b = 0; b < model.blocks(); ++b) {
      if (model.channel_spec(b).weight) continue;
      const auto& block = model.block(b);
      const int n = static_cast<int>(block.measured.size());
      const double rms = r.segment(block.offset, n).norm() / block.weight / std::sqrt(n);
      const double noise =
          std::max(rms * std::sqrt(model.residuals() / dof), 1e-13 * block.scale);
      model.set_weight(b, 1.0 / noise);
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
    const auto& free = model.free(i);
    ParameterEstimate e;
    e.name = model.slot(i).name;
    e.unit = free.parameter.unit;
    if (model.slot(i).record >= 0) e.record = records[model.slot(i).record].source;
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
  for (int b = 0; b < model.blocks(); ++b) {
    const auto& block = model.block(b);
    const auto& spec = model.channel_spec(b);
    const auto& record = model.record(block.record);
    ChannelEstimate e;
    e.column = spec.column;
    e.link = spec.link;
    e.record = record.source;
    e.record_label = model.label(block.record);
    e.gain = best.theta[model.gain_index(b)];
    e.gain_se = std::sqrt(covariance(model.gain_index(b), model.gain_index(b)));
    e.offset = best.theta[model.offset_index(b)] * block.scale;
    e.offset_se =
        std::sqrt(covariance(model.offset_index(b), model.offset_index(b))) * block.scale;
    e.weight = block.weight;
    const int n = static_cast<int>(block.measured.size());
    e.samples = n;
    const Eigen::VectorXd fitted_trace = e.gain * m[b].array() + e.offset;
    e.fitted.assign(fitted_trace.data(), fitted_trace.data() + n);
    e.measured.assign(block.measured.data(), block.measured.data() + n);
    e.time_s.assign(record.time_s.begin() + block.begin, record.time_s.begin() + block.end);
    e.rms_residual = (fitted_trace - block.measured).norm() / std::sqrt(n);
    result.channels.push_back(e);
  }

  for (int j : fitted) {
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
