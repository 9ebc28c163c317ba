#include "identify/fit_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "millkit/identify/fit.h"

namespace millkit::identify {

FitModel::FitModel(const driveline::Scene& scene, const std::vector<Oscillogram>& records,
                   const FitConfig& config, const std::vector<double>& weights)
    : scene_(scene), records_(records), config_(config) {
  const int record_count = static_cast<int>(records.size());
  labels_ = RecordLabels(records);
  for (int i = 0; i < static_cast<int>(config.free.size()); ++i) {
    const auto& free = config.free[i];
    const auto& name = free.parameter.name;
    if (free.per_record && record_count > 1) {
      for (int r = 0; r < record_count; ++r) {
        slots_.push_back({i, r, name + "@" + labels_[r], ParameterMap(free)});
      }
    } else {
      slots_.push_back({i, -1, name, ParameterMap(free)});
    }
  }
  for (int r = 0; r < record_count; ++r) {
    const auto& record = records[r];
    const auto [begin, end] = record.WindowRange(config.window_start_s, config.window_end_s);
    for (int c = 0; c < static_cast<int>(config.channels.size()); ++c) {
      const auto& spec = config.channels[c];
      Block b;
      b.record = r;
      b.channel = c;
      b.column = record.ChannelIndex(spec.column);
      b.begin = begin;
      b.end = b.full_end = end;
      double peak = 0.0;
      for (int k = begin; k < end; ++k) peak = std::max(peak, std::abs(record.values[b.column][k]));
      b.scale = std::max(peak, std::numeric_limits<double>::min());
      b.weight = weights.at(blocks_.size());
      b.gain_lower = spec.gain_lower;
      b.gain_upper = spec.gain_upper;
      const double limit = spec.offset_limit_Nm ? *spec.offset_limit_Nm : peak;
      b.offset_lower_Nm = -limit;
      b.offset_upper_Nm = limit;
      blocks_.push_back(std::move(b));
    }
    onsets_.push_back(OnsetTime(r));
  }
  SetStage(1.0);
}

void FitModel::SetStage(double divisor) {
  jacobian_memo_.valid = false;  // another window
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

int FitModel::FewestSamples(double divisor) const {
  int fewest = std::numeric_limits<int>::max();
  for (const auto& b : blocks_) fewest = std::min(fewest, StageEnd(b, divisor) - b.begin);
  return fewest;
}

int FitModel::StageEnd(const Block& b, double divisor) const {
  if (divisor == 1.0) return b.full_end;
  const double onset = onsets_[b.record];
  const double end_s = onset + (config_.window_end_s - onset) / divisor;
  return std::min(b.full_end, records_[b.record].WindowRange(config_.window_start_s, end_s).second);
}

// When record r's response starts: the first time any channel leaves its initial level by a
// fifth of its largest excursion in the window.
double FitModel::OnsetTime(int r) const {
  const auto& record = records_[r];
  double onset = record.time_s[blocks_.back().full_end - 1];
  for (const auto& b : blocks_) {
    if (b.record != r) continue;
    const auto& y = record.values[b.column];
    const double initial = y[b.begin];
    double excursion = 0.0;
    for (int k = b.begin; k < b.full_end; ++k)
      excursion = std::max(excursion, std::abs(y[k] - initial));
    for (int k = b.begin; k < b.full_end; ++k) {
      if (std::abs(y[k] - initial) > 0.2 * excursion) {
        onset = std::min(onset, record.time_s[k]);
        break;
      }
    }
  }
  return onset;
}

std::vector<int> FitModel::ConstantIndices() const {
  std::vector<int> constant;
  for (int b = 0; b < blocks(); ++b) {
    if (!channel_spec(b).fit_gain) constant.push_back(gain_index(b));
    if (!channel_spec(b).fit_offset) constant.push_back(offset_index(b));
  }
  return constant;
}

std::vector<int> FitModel::FittedIndices() const {
  const auto constant = ConstantIndices();
  std::vector<int> fitted;
  for (int j = 0; j < size(); ++j) {
    if (std::find(constant.begin(), constant.end(), j) == constant.end()) fitted.push_back(j);
  }
  return fitted;
}

std::string FitModel::NuisanceName(int b, bool gain) const {
  std::string name = gain ? "gain." : "offset.";
  name += channel_spec(b).column;
  if (records_.size() > 1) {
    name += "@";
    name += labels_[blocks_[b].record];
  }
  return name;
}

driveline::Scene FitModel::RecordScene(int r, const double* u, const std::vector<int>& frozen,
                                       std::vector<driveline::SceneParameter>* parameters,
                                       std::vector<int>* slots) const {
  driveline::Scene scene = scene_;
  for (int s = 0; s < this->parameters(); ++s) {
    if (slots_[s].record < 0 || slots_[s].record == r) {
      free(s).parameter.Set(Physical(s, u[s]), &scene);
      if (parameters == nullptr) continue;
      if (std::find(frozen.begin(), frozen.end(), s) != frozen.end()) continue;
      parameters->push_back(free(s).parameter);
      slots->push_back(s);
    }
  }
  return scene;
}

void FitModel::CountSimulation() const {
  const long simulations = ++*simulations_;
  if (progress_) {
    const std::lock_guard lock(*progress_mutex_);
    progress_(activity_, simulations);
  }
}

void FitModel::ToUnits(int r, const double* u, const std::vector<int>& slots,
                       const std::vector<Eigen::MatrixXd>& derivatives,
                       std::vector<Eigen::MatrixXd>* dm) const {
  const size_t channels = config_.channels.size();
  for (size_t c = 0; c < channels; ++c) {
    // d/du = d/dp · dp/du per slot.
    Eigen::MatrixXd& out = (*dm)[r * channels + c];
    out.setZero(derivatives[c].rows(), this->parameters());
    for (size_t j = 0; j < slots.size(); ++j) {
      out.col(slots[j]) = derivatives[c].col(static_cast<int>(j)) *
                          slots_[slots[j]].map.PhysicalPerUnit(u[slots[j]]);
    }
  }
}

bool FitModel::Torques(const double* u, std::vector<Eigen::VectorXd>* m, int only_record,
                       std::vector<driveline::RecordedRun>* kept) const {
  m->resize(blocks_.size());
  if (kept != nullptr) kept->resize(records_.size());
  std::vector<Eigen::VectorXd> torques;
  const size_t channels = config_.channels.size();
  for (int r = 0; r < static_cast<int>(records_.size()); ++r) {
    if (only_record >= 0 && r != only_record) continue;
    const driveline::Scene scene = RecordScene(r, u, {}, nullptr, nullptr);
    // Blocks of a record are consecutive, in config channel order.
    const Block& first = blocks_[r * channels];
    CountSimulation();
    std::string why;
    if (!SimulateChannels(scene, records_[r], TimeOrigin(config_, records_[r]), config_.channels,
                          first.begin, first.end, &torques, &why,
                          kept != nullptr ? &(*kept)[r] : nullptr)) {
      last_failure_ = records_.size() > 1 ? records_[r].source + ": " + why : why;
      return false;
    }
    for (size_t c = 0; c < torques.size(); ++c) (*m)[r * channels + c] = std::move(torques[c]);
  }
  return true;
}

bool FitModel::TorquesWithDerivatives(const double* u, std::vector<Eigen::VectorXd>* m,
                                      std::vector<Eigen::MatrixXd>* dm, bool* available,
                                      const std::vector<int>& frozen) const {
  m->resize(blocks_.size());
  dm->resize(blocks_.size());
  *available = true;
  std::vector<Eigen::VectorXd> torques;
  std::vector<Eigen::MatrixXd> derivatives;
  const size_t channels = config_.channels.size();
  for (int r = 0; r < static_cast<int>(records_.size()); ++r) {
    std::vector<driveline::SceneParameter> scene_parameters;
    std::vector<int> slots;  // the slot of each scene parameter
    const driveline::Scene scene = RecordScene(r, u, frozen, &scene_parameters, &slots);
    const Block& first = blocks_[r * channels];
    CountSimulation();
    std::string why, unavailable;
    if (!SimulateChannels(scene, records_[r], TimeOrigin(config_, records_[r]), config_.channels,
                          first.begin, first.end, &torques, &why, scene_parameters, &derivatives,
                          &unavailable)) {
      last_failure_ = records_.size() > 1 ? records_[r].source + ": " + why : why;
      return false;
    }
    if (!unavailable.empty()) *available = false;
    for (size_t c = 0; c < torques.size(); ++c) (*m)[r * channels + c] = std::move(torques[c]);
    if (*available) ToUnits(r, u, slots, derivatives, dm);
  }
  return true;
}

bool FitModel::DerivativesAlong(const std::vector<driveline::RecordedRun>& kept, const double* u,
                                std::vector<Eigen::MatrixXd>* dm, bool* available,
                                const std::vector<int>& frozen) const {
  dm->resize(blocks_.size());
  *available = true;
  std::vector<Eigen::MatrixXd> derivatives;
  const size_t channels = config_.channels.size();
  for (int r = 0; r < static_cast<int>(records_.size()); ++r) {
    std::vector<driveline::SceneParameter> scene_parameters;
    std::vector<int> slots;
    RecordScene(r, u, frozen, &scene_parameters, &slots);  // the scene is the kept run's
    const Block& first = blocks_[r * channels];
    CountSimulation();
    std::string why, unavailable;
    if (!ChannelDerivatives(kept[r], records_[r], TimeOrigin(config_, records_[r]),
                            config_.channels, first.begin, first.end, scene_parameters,
                            &derivatives, &unavailable, &why)) {
      last_failure_ = records_.size() > 1 ? records_[r].source + ": " + why : why;
      return false;
    }
    if (!unavailable.empty()) *available = false;
    if (*available) ToUnits(r, u, slots, derivatives, dm);
  }
  return true;
}

Eigen::MatrixXd FitModel::ProjectedDerivative(int b, const Eigen::VectorXd& m,
                                              const Eigen::MatrixXd& dm, const Nuisance& n) const {
  const auto& spec = channel_spec(b);
  const auto& block = blocks_[b];
  const auto& y = block.measured;
  const double count = static_cast<double>(y.size());
  const bool gain_free = spec.fit_gain && !n.gain_at_bound;
  const bool offset_free = spec.fit_offset && !n.offset_at_bound;
  // Per parameter column: y·dm, m·dm and Σ dm.
  const Eigen::RowVectorXd y_dm = y.transpose() * dm;
  const Eigen::RowVectorXd m_dm = m.transpose() * dm;
  const Eigen::RowVectorXd sum_dm = dm.colwise().sum();
  Eigen::RowVectorXd dg = Eigen::RowVectorXd::Zero(dm.cols());
  Eigen::RowVectorXd d_offset = Eigen::RowVectorXd::Zero(dm.cols());
  const double smm = m.squaredNorm(), sm = m.sum();
  // The normal equations of the free ones, differentiated: with both free
  //   smm g + sm o = y·m,  sm g + N o = Σy  →  [smm sm; sm N] [dg; do] = [y·dm − 2g m·dm − o Σdm;
  //   −g Σdm].
  if (gain_free && offset_free) {
    const double det = smm * count - sm * sm;
    if (det > 0.0) {
      const Eigen::RowVectorXd r1 = y_dm - 2.0 * n.gain * m_dm - n.offset_Nm * sum_dm;
      const Eigen::RowVectorXd r2 = -n.gain * sum_dm;
      dg = (count * r1 - sm * r2) / det;
      d_offset = (smm * r2 - sm * r1) / det;
    }
  } else if (gain_free && smm > 0.0) {
    dg = (y_dm - n.offset_Nm * sum_dm - 2.0 * n.gain * m_dm) / smm;
  } else if (offset_free) {
    d_offset = -n.gain * sum_dm / count;
  }
  Eigen::MatrixXd derivative = n.gain * dm + m * dg;
  derivative.rowwise() += d_offset;
  return block.weight * derivative;
}

Nuisance FitModel::SolveNuisance(int b, const Eigen::VectorXd& m) const {
  const auto& spec = channel_spec(b);
  const auto& block = blocks_[b];
  const auto& y = block.measured;
  const double n = static_cast<double>(y.size());
  const double sm = m.sum(), smm = m.squaredNorm(), sy = y.sum(), sym = m.dot(y);
  // Σ (y − g m − o)² up to the constant Σ y².
  const auto cost = [&](double g, double o) {
    return -2.0 * g * sym - 2.0 * o * sy + g * g * smm + 2.0 * g * o * sm + n * o * o;
  };
  const auto clamp_gain = [&](double g) {
    return std::clamp(g, block.gain_lower, block.gain_upper);
  };
  const auto clamp_offset = [&](double o) {
    return std::clamp(o, block.offset_lower_Nm, block.offset_upper_Nm);
  };
  // Best gain for a given offset, and best offset for a given gain (each clamped).
  const auto gain_for = [&](double o) {
    return smm > 0.0 ? clamp_gain((sym - o * sm) / smm) : 1.0;
  };
  const auto offset_for = [&](double g) { return clamp_offset((sy - g * sm) / n); };
  Nuisance best;
  if (spec.fit_gain && spec.fit_offset) {
    // A convex quadratic over a box: its minimum is the free one when inside, else on an edge,
    // where the one-dimensional minimum clamped to the edge is the edge's best.
    std::vector<std::pair<double, double>> candidates;
    const double det = smm * n - sm * sm;
    if (det > 1e-14 * smm * n) {
      const double g = (sym * n - sm * sy) / det;
      const double o = (smm * sy - sm * sym) / det;
      if (g >= block.gain_lower && g <= block.gain_upper && o >= block.offset_lower_Nm &&
          o <= block.offset_upper_Nm) {
        candidates.emplace_back(g, o);
      }
    }
    if (candidates.empty()) {
      for (const double g : {block.gain_lower, block.gain_upper})
        candidates.emplace_back(g, offset_for(g));
      for (const double o : {block.offset_lower_Nm, block.offset_upper_Nm}) {
        candidates.emplace_back(gain_for(o), o);
      }
      // The unit gain with its best offset (a torque-free model: no gain to fit).
      candidates.emplace_back(clamp_gain(1.0), offset_for(clamp_gain(1.0)));
    }
    double lowest = std::numeric_limits<double>::infinity();
    for (const auto& [g, o] : candidates) {
      if (const double c = cost(g, o); c < lowest) {
        lowest = c;
        best.gain = g;
        best.offset_Nm = o;
      }
    }
  } else if (spec.fit_gain) {
    best.gain = gain_for(0.0);
  } else if (spec.fit_offset) {
    best.offset_Nm = offset_for(1.0);
  }
  const auto near = [](double v, double bound) {
    return std::abs(v - bound) <= 1e-12 * std::max(1.0, std::abs(bound));
  };
  best.gain_at_bound =
      spec.fit_gain && (near(best.gain, block.gain_lower) || near(best.gain, block.gain_upper));
  best.offset_at_bound = spec.fit_offset && (near(best.offset_Nm, block.offset_lower_Nm) ||
                                             near(best.offset_Nm, block.offset_upper_Nm));
  return best;
}

void FitModel::BlockResiduals(int b, const Eigen::VectorXd& m, const Nuisance& n, double* r) const {
  const auto& block = blocks_[b];
  Eigen::Map<Eigen::VectorXd>(r + block.offset, block.measured.size()) =
      block.weight * (n.gain * m.array() + n.offset_Nm - block.measured.array()).matrix();
}

bool FitModel::Project(const std::vector<Eigen::VectorXd>& m, Eigen::VectorXd* r,
                       std::vector<Nuisance>* nuisance) const {
  r->resize(residuals_);
  if (nuisance != nullptr) nuisance->resize(blocks_.size());
  for (int b = 0; b < blocks(); ++b) {
    const Nuisance n = SolveNuisance(b, m[b]);
    BlockResiduals(b, m[b], n, r->data());
    if (nuisance != nullptr) (*nuisance)[b] = n;
  }
  return r->allFinite();
}

bool FitModel::ProjectedResiduals(const double* u, Eigen::VectorXd* r,
                                  std::vector<Nuisance>* nuisance,
                                  std::vector<Eigen::VectorXd>* m) const {
  std::vector<Eigen::VectorXd> local;
  if (m == nullptr) m = &local;
  return Torques(u, m) && Project(*m, r, nuisance);
}

double FitModel::ProjectedCost(const double* u) const {
  Eigen::VectorXd r;
  if (!ProjectedResiduals(u, &r)) return std::numeric_limits<double>::infinity();
  return 0.5 * r.squaredNorm();
}

bool FitModel::JacobianMemo::Matches(const std::vector<double>& at,
                                     const std::vector<Nuisance>& with, double h,
                                     Derivatives kind) const {
  if (!valid || at != u || h != step || kind != derivatives || with.size() != nuisance.size()) {
    return false;
  }
  for (size_t b = 0; b < with.size(); ++b) {
    const Nuisance &x = with[b], &y = nuisance[b];
    if (x.gain != y.gain || x.offset_Nm != y.offset_Nm || x.gain_at_bound != y.gain_at_bound ||
        x.offset_at_bound != y.offset_at_bound) {
      return false;
    }
  }
  return true;
}

bool FitModel::FullJacobian(const std::vector<double>& u, const std::vector<Nuisance>& nuisance,
                            double step, Derivatives derivatives, Eigen::VectorXd* r,
                            Eigen::MatrixXd* jacobian) const {
  JacobianMemo& memo = jacobian_memo_;
  if (memo.Matches(u, nuisance, step, derivatives)) {
    *r = memo.r;
    *jacobian = memo.jacobian;
    return true;
  }
  memo.valid = false;
  if (!FullJacobianAnew(u, nuisance, step, derivatives, r, jacobian)) return false;
  memo.u = u;
  memo.nuisance = nuisance;
  memo.step = step;
  memo.derivatives = derivatives;
  memo.r = *r;
  memo.jacobian = *jacobian;
  memo.valid = true;
  return true;
}

bool FitModel::FullJacobianAnew(const std::vector<double>& u, const std::vector<Nuisance>& nuisance,
                                double step, Derivatives derivatives, Eigen::VectorXd* r,
                                Eigen::MatrixXd* jacobian) const {
  std::vector<Eigen::VectorXd> m;
  std::vector<Eigen::MatrixXd> dm;
  bool exact = false;  // the scene columns from the sensitivities
  if (derivatives == Derivatives::kSensitivity) {
    if (!TorquesWithDerivatives(u.data(), &m, &dm, &exact, {})) return false;
  } else if (!Torques(u.data(), &m)) {
    return false;
  }
  r->resize(residuals_);
  for (int b = 0; b < blocks(); ++b) BlockResiduals(b, m[b], nuisance[b], r->data());
  auto& jac = *jacobian;
  jac.setZero(residuals_, size());
  for (int b = 0; b < blocks(); ++b) {
    const auto& block = blocks_[b];
    const int n = static_cast<int>(block.measured.size());
    jac.block(block.offset, gain_index(b), n, 1) = block.weight * m[b];
    jac.block(block.offset, offset_index(b), n, 1).setConstant(block.weight * block.scale);
    if (exact) {
      jac.block(block.offset, 0, n, parameters()) = block.weight * nuisance[b].gain * dm[b];
    }
  }
  if (exact) return true;
  std::vector<double> probe = u;
  std::vector<Eigen::VectorXd> m1, m2;
  for (int i = 0; i < parameters(); ++i) {
    const int only = slots_[i].record;
    const double u0 = u[i];
    const double h = step;
    const auto simulate = [&](double value, std::vector<Eigen::VectorXd>* out) {
      probe[i] = value;
      const bool ok = Torques(probe.data(), out, only);
      probe[i] = u0;
      return ok;
    };
    const auto write = [&](const auto& derivative_of) {
      for (int b = 0; b < blocks(); ++b) {
        const auto& block = blocks_[b];
        if (only >= 0 && block.record != only) continue;
        jac.block(block.offset, i, block.measured.size(), 1) =
            block.weight * nuisance[b].gain * derivative_of(b);
      }
    };
    // Central where both neighbours are inside [0, 1] and simulate; else second-order one-sided
    // on the side that does.
    int kind = 0;  // 0 central, +1 forward, −1 backward
    if (u0 - h < 0.0)
      kind = +1;
    else if (u0 + h > 1.0)
      kind = -1;
    bool done = false;
    if (kind == 0) {
      const bool up = simulate(u0 + h, &m1);
      const bool down = up && simulate(u0 - h, &m2);
      done = up && down;
      if (!done) kind = up ? +1 : -1;
    }
    if (done) {
      write([&](int b) { return Eigen::VectorXd((m1[b] - m2[b]) / (2.0 * h)); });
      continue;
    }
    if (u0 + 2 * kind * h < 0.0 || u0 + 2 * kind * h > 1.0) return false;
    if (!simulate(u0 + kind * h, &m1) || !simulate(u0 + 2 * kind * h, &m2)) return false;
    write([&](int b) {
      return Eigen::VectorXd(kind * (4.0 * m1[b] - 3.0 * m[b] - m2[b]) / (2.0 * h));
    });
  }
  return true;
}

ProjectedResidual::ProjectedResidual(const FitModel& model, double step, Derivatives derivatives,
                                     std::vector<int> frozen)
    : model_(model), step_(step), derivatives_(derivatives), frozen_(std::move(frozen)) {
  set_num_residuals(model.residuals());
  mutable_parameter_block_sizes()->push_back(model.parameters());
}

bool ProjectedResidual::Evaluate(double const* const* parameters, double* residuals,
                                 double** jacobians) const {
  const int p = model_.parameters();
  const int n = model_.residuals();
  std::vector<double> u(p);
  for (int i = 0; i < p; ++i) u[i] = ParameterMap::UnitFromAngle(parameters[0][i]);
  const bool want_jacobian = jacobians != nullptr && jacobians[0] != nullptr;
  if (want_jacobian) jacobian_skipped_ = false;
  std::vector<Eigen::VectorXd> m;
  Eigen::VectorXd r;
  if (want_jacobian && derivatives_ == Derivatives::kSensitivity) {
    std::vector<Eigen::MatrixXd> dm;
    bool available = false;
    if (!kept_point_.empty() && std::equal(kept_point_.begin(), kept_point_.end(), parameters[0])) {
      // The point of the latest plain evaluation (a step Levenberg–Marquardt just accepted).
      kept_point_.clear();
      m = std::move(kept_m_);
      r = std::move(kept_r_);
      if (SkipJacobian(parameters[0], r, residuals, jacobians[0])) return true;
      if (!model_.DerivativesAlong(kept_runs_, u.data(), &dm, &available, frozen_)) return false;
    } else if (!model_.TorquesWithDerivatives(u.data(), &m, &dm, &available, frozen_) ||
               !model_.Project(m, &r)) {
      return false;
    }
    Eigen::Map<Eigen::VectorXd>(residuals, n) = r;
    if (available) {
      std::vector<Nuisance> nuisance(model_.blocks());
      for (int b = 0; b < model_.blocks(); ++b) nuisance[b] = model_.SolveNuisance(b, m[b]);
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
          jacobians[0], n, p);
      for (int b = 0; b < model_.blocks(); ++b) {
        const auto& block = model_.block(b);
        jac.middleRows(block.offset, block.measured.size()) =
            model_.ProjectedDerivative(b, m[b], dm[b], nuisance[b]);
      }
      for (int i = 0; i < p; ++i) {
        if (std::find(frozen_.begin(), frozen_.end(), i) != frozen_.end())
          jac.col(i).setZero();
        else
          jac.col(i) *= ParameterMap::UnitPerAngle(parameters[0][i]);
      }
      Measure(jac, r, parameters[0]);
      return true;
    }
    // Not available here (a grazing event, a degenerate switch): forward differences.
  } else {
    // A plain evaluation keeps its runs for sensitivities at the same point (with sensitivities
    // this branch is taken without a Jacobian).
    const bool keep = derivatives_ == Derivatives::kSensitivity;
    kept_point_.clear();
    if (!model_.Torques(u.data(), &m, -1, keep ? &kept_runs_ : nullptr) || !model_.Project(m, &r)) {
      return false;
    }
    Eigen::Map<Eigen::VectorXd>(residuals, n) = r;
    if (keep) {
      kept_point_.assign(parameters[0], parameters[0] + p);
      kept_m_ = std::move(m);
      kept_r_ = std::move(r);
      return true;
    }
  }
  if (!want_jacobian || SkipJacobian(parameters[0], r, residuals, jacobians[0])) return true;
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
      jacobians[0], n, p);
  jac.setZero();
  Eigen::VectorXd r1, r2;
  std::vector<Eigen::VectorXd> probe_m;
  for (int i = 0; i < p; ++i) {
    if (std::find(frozen_.begin(), frozen_.end(), i) != frozen_.end()) continue;
    const double u0 = u[i];
    // A per-record slot re-simulates only its record; the other records keep their torques.
    const int only = model_.slot(i).record;
    const auto probe = [&](double value, Eigen::VectorXd* out) {
      u[i] = value;
      probe_m = m;
      const bool ok = model_.Torques(u.data(), &probe_m, only) && model_.Project(probe_m, out);
      u[i] = u0;
      return ok;
    };
    if (derivatives_ == Derivatives::kCentral && u0 - step_ >= 0.0 && u0 + step_ <= 1.0 &&
        probe(u0 + step_, &r1) && probe(u0 - step_, &r2)) {
      jac.col(i) = (r1 - r2) / (2.0 * step_);
    } else {
      // A probe the solver cannot run (a rare event configuration it rejects) is retried on the
      // other side before the evaluation is declared failed.
      double h = u0 + step_ > 1.0 ? -step_ : step_;
      if (!probe(u0 + h, &r1)) {
        h = -h;
        if (u0 + h < 0.0 || u0 + h > 1.0 || !probe(u0 + h, &r1)) return false;
      }
      jac.col(i) = (r1 - r) / h;
    }
    jac.col(i) *= ParameterMap::UnitPerAngle(parameters[0][i]);
  }
  Measure(jac, r, parameters[0]);
  return true;
}

bool ProjectedResidual::SkipJacobian(const double* phi, const Eigen::VectorXd& r, double* residuals,
                                     double* jacobian) const {
  // Past the start (whose Jacobian sets Levenberg–Marquardt's scaling), Ceres asks for one only
  // at a point it has just accepted.
  if (iteration_ < 1) return false;
  if (stop_ && stop_(phi, 0.5 * r.squaredNorm())) {
    stopped_ = true;
  } else if (measure_step_ || iteration_ < last_iteration_) {
    return false;
  }
  const auto n = static_cast<Eigen::Index>(r.size());
  Eigen::Map<Eigen::VectorXd>(residuals, n) = r;
  Eigen::Map<Eigen::VectorXd>(jacobian, n * model_.parameters()).setZero();
  jacobian_skipped_ = true;
  return true;
}

void ProjectedResidual::Measure(const Eigen::Ref<const Eigen::MatrixXd>& jacobian,
                                const Eigen::VectorXd& residuals, const double* phi) const {
  jacobian_point_.assign(phi, phi + model_.parameters());
  if (!measure_step_) return;
  double variance = 0.0;
  remaining_step_se_ = GaussNewtonStepInStandardErrors(jacobian, residuals, &variance);
  if (std::isfinite(remaining_step_se_)) {
    precision_ = jacobian.transpose() * jacobian / variance;
  } else {
    precision_.resize(0, 0);
  }
}

double GaussNewtonStepInStandardErrors(const Eigen::Ref<const Eigen::MatrixXd>& jacobian,
                                       const Eigen::VectorXd& residuals, double* variance) {
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(jacobian);
  const Eigen::Index rank = qr.rank();
  const Eigen::Index freedom = residuals.size() - rank;
  if (rank == 0 || freedom <= 0) return std::numeric_limits<double>::quiet_NaN();
  const Eigen::VectorXd rotated = qr.householderQ().adjoint() * residuals;
  const double explained = rotated.head(rank).squaredNorm();
  const double left = rotated.tail(freedom).squaredNorm();
  if (!(left > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (variance != nullptr) *variance = left / static_cast<double>(freedom);
  return std::sqrt(explained / (left / static_cast<double>(freedom)));
}

}  // namespace millkit::identify
