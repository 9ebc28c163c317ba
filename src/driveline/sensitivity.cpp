// Forward sensitivities alongside the exact solver's run; see sensitivity.h for the equations.
//
// The run is the exact solver's (hybrid_driver.h): a HybridObserver is told every stop (leg end,
// event, breakpoint, output time) with the state there, and carries the sensitivities S = [s_1 …
// s_P] from stop to stop in the phase set of the leg. It works in the solver's scaled
// coordinates, ỹ = D⁻¹ z and S̃_j = σ_j D⁻¹ s_j (σ_j the parameter's magnitude), where
// M̃ = D⁻¹ M D has a norm near the fastest mode's rate and M̃_j = σ_j D⁻¹ M_j D is of the same size.
#include "millkit/driveline/sensitivity.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <unsupported/Eigen/MatrixFunctions>

#include "driveline/hybrid_driver.h"
#include "millkit/io/input_error.h"

namespace millkit::driveline {
namespace {

// The stencil step, relative to the parameter's magnitude.
constexpr double kRelativeStep = 1e-3;
// Full sample steps in one phase set before its propagators over the step are built.
constexpr long kStepsBeforeCaching = 8;
// Legs whose Taylor series would need more pieces (‖M̃‖∞ τ) take the matrix exponential instead.
constexpr double kMaxTaylorPieces = 16.0;
constexpr int kMaxTaylorTerms = 60;
constexpr double kEps = std::numeric_limits<double>::epsilon();
// A surface crossed at a rate below this fraction of its terms' size grazes: the event time's
// derivative is not defined.
constexpr double kGrazingRate = 1e-9;

// d/dp of a quantity from its values at p + offset·δ: Σ weight · f(p + offset·δ) / δ.
struct Stencil {
  std::vector<double> offsets;
  std::vector<double> weights;
};

Stencil StencilFor(double value, double step, const ParameterRange& range) {
  const bool below = value - 2.0 * step < range.lower ||
                     (!range.lower_inclusive && value - 2.0 * step <= range.lower);
  const bool above = value + 2.0 * step > range.upper;
  if (!below && !above) return {{-2, -1, 1, 2}, {1.0 / 12, -8.0 / 12, 8.0 / 12, -1.0 / 12}};
  const double side = below ? 1.0 : -1.0;
  Stencil stencil{{0, side, 2 * side, 3 * side, 4 * side},
                  {-25.0 / 12, 48.0 / 12, -36.0 / 12, 16.0 / 12, -3.0 / 12}};
  for (double& w : stencil.weights) w *= side;
  return stencil;
}

// The magnitude σ of a parameter: the stencil step is kRelativeStep σ, and S̃ is scaled by it.
double Magnitude(const SceneParameter& parameter, const Scene& scene, double value) {
  using Kind = SceneParameter::Kind;
  if (value != 0.0 && parameter.kind != Kind::kGapPosition) return std::abs(value);
  switch (parameter.kind) {
    case Kind::kGapPosition:
      return 1.0;
    case Kind::kBiteTime:
      return scene.duration_s;
    case Kind::kDamping: {
      // Zero damping: the link's critical damping scale, c / (2π · 100 Hz).
      const Link& link = scene.links[parameter.index];
      return std::max(link.stiffness_Nm_per_rad / (2.0 * M_PI * 100.0), 1e-6);
    }
    default:
      return 1.0;
  }
}

bool SameStructure(const Model& a, const Model& b) {
  return a.augmented_size() == b.augmented_size() && a.surface_count() == b.surface_count() &&
         a.backlash_link_count() == b.backlash_link_count() && a.has_drive() == b.has_drive() &&
         a.reduction().link_rigid == b.reduction().link_rigid &&
         a.reduction().group_of_mass == b.reduction().group_of_mass;
}

// One parameter's derivative data: the models of its stencil.
struct ParameterModels {
  SceneParameter parameter;
  double magnitude = 1.0;  // σ
  double step = 0.0;       // δ
  Stencil stencil;
  std::vector<std::unique_ptr<Model>> models;  // per stencil offset; null for offset 0
  bool bite_time = false;
  // d/dp of a model quantity: Σ weight · f(model at offset) / δ.
  template <typename Quantity>
  Eigen::MatrixXd Derivative(const Model& nominal, const Quantity& quantity) const {
    Eigen::MatrixXd sum;
    for (size_t k = 0; k < models.size(); ++k) {
      const Model& model = models[k] ? *models[k] : nominal;
      Eigen::MatrixXd value = quantity(model);
      if (k == 0)
        sum = stencil.weights[k] * value;
      else
        sum += stencil.weights[k] * value;
    }
    return sum / step;
  }
};

// Everything the pass needs of one phase set.
struct PhaseSet {
  Eigen::MatrixXd m;                      // M (unscaled)
  Eigen::MatrixXd m_scaled;               // M̃
  std::vector<Eigen::MatrixXd> m_p;       // M̃_j (empty matrix when M_j = 0)
  Eigen::MatrixXd torque;                 // T: reduced link torques = T z
  std::vector<Eigen::MatrixXd> torque_p;  // T_j, built on the first output in the phase set
  double norm = 0.0;                      // ‖M̃‖∞
  long full_steps = 0;
  bool cached = false;
  Eigen::MatrixXd e;               // exp(M̃ h)
  std::vector<Eigen::MatrixXd> f;  // F̃_j(h)
};

class SensitivityPass final : public HybridObserver {
 public:
  SensitivityPass(const Model& model, std::vector<ParameterModels> parameters,
                  const Eigen::VectorXd& scale, double step, int samples, bool given_state)
      : model_(model),
        parameters_(std::move(parameters)),
        d_(scale),
        d_inverse_(scale.cwiseInverse()),
        h_(step),
        n_(model.augmented_size()),
        p_(static_cast<int>(parameters_.size())),
        given_state_(given_state) {
    const int links = static_cast<int>(model.scene().links.size());
    out_.assign(p_, Eigen::MatrixXd::Zero(samples, links));
    surfaces_p_.resize(p_);
    for (int j = 0; j < p_; ++j) {
      surfaces_p_[j] = parameters_[j].Derivative(
          model_, [](const Model& m) -> Eigen::MatrixXd { return m.surfaces(); });
    }
  }

  const std::string& unavailable() const { return unavailable_; }
  std::vector<Eigen::MatrixXd> TakeOutputs() { return std::move(out_); }

  void Started(const Eigen::VectorXd& z0, const Phases& /*phases*/) override {
    s_.setZero(n_, p_);
    for (int j = 0; j < p_; ++j) {
      const Eigen::VectorXd ds = parameters_[j].Derivative(
          model_, [](const Model& m) -> Eigen::MatrixXd { return m.InitialState(); });
      Eigen::VectorXd s = ds;
      // A given initial state (options.initial_state) holds x whatever the parameters.
      if (given_state_) s.head(model_.state_size()).setZero();
      SetS(j, s);
    }
    z_ = z0;
  }

  void LegEnded(double elapsed, const Phases& phases, const Eigen::VectorXd& z,
                bool blind) override {
    if (!unavailable_.empty()) return;
    if (blind) {
      unavailable_ = "the run escaped a degenerate switch (chattering contact)";
      return;
    }
    Propagate(Data(phases), elapsed);
    z_ = z;
  }

  void Switched(const Phases& before, const Phases& after,
                const std::vector<Model::KnownSide>& crossed) override {
    if (!unavailable_.empty()) return;
    const Eigen::VectorXd f_before = Data(before).m * z_;
    const Eigen::VectorXd f_after = Data(after).m * z_;
    const Eigen::VectorXd jump = f_before - f_after;
    const double size = (d_inverse_.asDiagonal() * f_before).cwiseAbs().maxCoeff();
    if ((d_inverse_.asDiagonal() * jump).cwiseAbs().maxCoeff() <= 1e-12 * size) return;
    // The crossed surface with the fastest rate, relative to the size of its terms.
    int surface = -1;
    double best = 0.0, rate = 0.0;
    for (const Model::KnownSide& side : crossed) {
      const auto row = model_.surfaces().row(side.surface);
      const double r = row.dot(f_before);
      const double terms = row.cwiseAbs().dot(f_before.cwiseAbs());
      const double relative = terms > 0.0 ? std::abs(r) / terms : 0.0;
      if (relative > best) {
        best = relative;
        rate = r;
        surface = side.surface;
      }
    }
    if (surface < 0 || best <= kGrazingRate) {
      unavailable_ =
          "an event grazes its switching surface (the event sequence is not locally "
          "constant)";
      return;
    }
    const auto row = model_.surfaces().row(surface);
    for (int j = 0; j < p_; ++j) {
      const double dt = -(row.dot(S(j)) + surfaces_p_[j].row(surface).dot(z_)) / rate;
      SetS(j, S(j) + jump * dt);
    }
  }

  void BreakpointApplied(double breakpoint, const Eigen::VectorXd& z) override {
    if (!unavailable_.empty()) return;
    const int nx = model_.state_size();
    const int nw = model_.forcing_size();
    for (int j = 0; j < p_; ++j) {
      Eigen::VectorXd s = S(j);
      const ParameterModels& parameter = parameters_[j];
      if (parameter.bite_time) {
        // Every breakpoint moves with the bite time: x jumps by (x'⁻ − x'⁺), and the forcing's
        // sensitivity is minus its slope (piecewise linear: its slope's is zero).
        const Eigen::MatrixXd& m = current_->m;
        s.head(nx) += (m * z_ - m * z).head(nx);
        s.segment(nx, nw) = -z.segment(nx + nw, nw);
        s.segment(nx + nw, nw).setZero();
      } else {
        const Eigen::VectorXd forcing =
            parameter.Derivative(model_, [&](const Model& m) -> Eigen::MatrixXd {
              Eigen::VectorXd right = z;
              m.SetForcing(breakpoint, &right);
              return right.tail(2 * nw);
            });
        s.tail(2 * nw) = forcing;
      }
      SetS(j, s);
    }
    z_ = z;
  }

  void Recorded(int k, const Phases& phases) override {
    if (!unavailable_.empty()) return;
    PhaseSet& data = Data(phases);
    if (data.torque_p.empty()) {
      data.torque_p.resize(p_);
      for (int j = 0; j < p_; ++j) {
        data.torque_p[j] = parameters_[j].Derivative(model_, [&](const Model& m) {
          return m.LinkTorqueRows(phases, m.SystemMatrix(phases));
        });
      }
    }
    const ShaftFactors& factors = model_.shaft_factors();
    for (int j = 0; j < p_; ++j) {
      const Eigen::VectorXd torque = data.torque * S(j) + data.torque_p[j] * z_;
      for (int l = 0; l < torque.size(); ++l) out_[j](k, l) = torque[l] / factors.link[l];
    }
  }

 private:
  // s_j (unscaled) from S̃, and back.
  Eigen::VectorXd S(int j) const { return d_.asDiagonal() * s_.col(j) / parameters_[j].magnitude; }
  void SetS(int j, const Eigen::VectorXd& s) {
    s_.col(j) = parameters_[j].magnitude * (d_inverse_.asDiagonal() * s);
  }

  PhaseSet& Data(const Phases& phases) {
    auto found = cache_.find(phases);
    if (found != cache_.end()) {
      current_ = &found->second;
      return found->second;
    }
    PhaseSet& data = cache_[phases];
    data.m = model_.SystemMatrix(phases);
    data.m_scaled = d_inverse_.asDiagonal() * data.m * d_.asDiagonal();
    data.norm = data.m_scaled.cwiseAbs().rowwise().sum().maxCoeff();
    data.m_p.resize(p_);
    for (int j = 0; j < p_; ++j) {
      const Eigen::MatrixXd mp = parameters_[j].Derivative(
          model_, [&](const Model& m) -> Eigen::MatrixXd { return m.SystemMatrix(phases); });
      if (mp.cwiseAbs().maxCoeff() == 0.0) continue;
      data.m_p[j] = parameters_[j].magnitude * (d_inverse_.asDiagonal() * mp * d_.asDiagonal());
    }
    data.torque = model_.LinkTorqueRows(phases, data.m);
    current_ = &data;
    return data;
  }

  // exp(M̃ τ) and F̃_j(τ) by the matrix exponential of [M̃ M̃_j; 0 M̃] τ.
  void Exponentials(const PhaseSet& data, double tau, Eigen::MatrixXd* e,
                    std::vector<Eigen::MatrixXd>* f) const {
    *e = (data.m_scaled * tau).exp();
    f->assign(p_, Eigen::MatrixXd());
    Eigen::MatrixXd block = Eigen::MatrixXd::Zero(2 * n_, 2 * n_);
    block.topLeftCorner(n_, n_) = data.m_scaled * tau;
    block.bottomRightCorner(n_, n_) = data.m_scaled * tau;
    for (int j = 0; j < p_; ++j) {
      if (data.m_p[j].size() == 0) continue;
      block.topRightCorner(n_, n_) = data.m_p[j] * tau;
      (*f)[j] = block.exp().topRightCorner(n_, n_);
    }
  }

  void Propagate(PhaseSet& data, double tau) {
    if (tau <= 0.0) return;
    const Eigen::VectorXd y = d_inverse_.asDiagonal() * z_;
    const bool full_step = std::abs(tau - h_) <= 1e-10 * h_;
    if (full_step && !data.cached && ++data.full_steps >= kStepsBeforeCaching) {
      Exponentials(data, h_, &data.e, &data.f);
      data.cached = true;
    }
    if (full_step && data.cached) {
      s_ = data.e * s_;
      for (int j = 0; j < p_; ++j) {
        if (data.f[j].size() > 0) s_.col(j) += data.f[j] * y;
      }
      return;
    }
    const double pieces = std::ceil(data.norm * tau);
    if (pieces > kMaxTaylorPieces) {
      Eigen::MatrixXd e;
      std::vector<Eigen::MatrixXd> f;
      Exponentials(data, tau, &e, &f);
      s_ = e * s_;
      for (int j = 0; j < p_; ++j) {
        if (f[j].size() > 0) s_.col(j) += f[j] * y;
      }
      return;
    }
    // The Taylor series of [ỹ; S̃]' = [M̃ ỹ; M̃ S̃ + M̃_j ỹ] in pieces with ‖M̃ dt‖∞ <= 1.
    const int count = std::max(1, static_cast<int>(pieces));
    const double dt = tau / count;
    Eigen::VectorXd y_sum = y, y_term(n_), y_next(n_);
    Eigen::MatrixXd s_term(n_, p_), s_next(n_, p_);
    for (int piece = 0; piece < count; ++piece) {
      y_term = y_sum;
      s_term = s_;
      for (int k = 1; k <= kMaxTaylorTerms; ++k) {
        const double factor = dt / k;
        s_next.noalias() = data.m_scaled * s_term;
        for (int j = 0; j < p_; ++j) {
          if (data.m_p[j].size() > 0) s_next.col(j).noalias() += data.m_p[j] * y_term;
        }
        s_term = factor * s_next;
        y_next.noalias() = data.m_scaled * y_term;
        y_term = factor * y_next;
        y_sum += y_term;
        s_ += s_term;
        const double term = std::max(y_term.cwiseAbs().maxCoeff(), s_term.cwiseAbs().maxCoeff());
        const double sum = std::max(y_sum.cwiseAbs().maxCoeff(), s_.cwiseAbs().maxCoeff());
        if (term <= 0.25 * kEps * sum) break;
      }
    }
  }

  const Model& model_;
  std::vector<ParameterModels> parameters_;
  Eigen::VectorXd d_, d_inverse_;
  double h_;
  int n_, p_;
  bool given_state_;
  std::vector<Eigen::MatrixXd> surfaces_p_;  // G_j (unscaled)
  std::map<Phases, PhaseSet> cache_;
  PhaseSet* current_ = nullptr;  // the phase set of the latest leg
  Eigen::MatrixXd s_;            // S̃
  Eigen::VectorXd z_;            // the state at the latest stop
  std::vector<Eigen::MatrixXd> out_;
  std::string unavailable_;
};

}  // namespace

SensitivityResult SimulateWithSensitivities(const Scene& scene,
                                            const std::vector<SceneParameter>& parameters,
                                            const SimulationOptions& options) {
  SensitivityResult result;
  SimulationOptions run = options;
  run.solver = SolverKind::kExact;
  run.keep_samples = true;
  run.sample_sink = nullptr;
  const Model model(scene);
  run.Validate(model.scene());

  std::vector<ParameterModels> models;
  for (const SceneParameter& parameter : parameters) {
    ParameterModels entry;
    entry.parameter = parameter;
    const double value = parameter.Get(scene);
    entry.magnitude = Magnitude(parameter, scene, value);
    entry.step = kRelativeStep * entry.magnitude;
    entry.bite_time = parameter.kind == SceneParameter::Kind::kBiteTime;
    entry.stencil = StencilFor(value, entry.step, PhysicalRange(parameter.kind));
    for (const double offset : entry.stencil.offsets) {
      if (offset == 0.0) {
        entry.models.push_back(nullptr);
        continue;
      }
      Scene perturbed = scene;
      parameter.Set(value + offset * entry.step, &perturbed);
      try {
        entry.models.push_back(std::make_unique<Model>(std::move(perturbed)));
      } catch (const InputError& error) {
        result.unavailable = parameter.name + ": the scene at a neighbouring value is invalid (" +
                             error.what() + ")";
        break;
      }
      if (!SameStructure(model, *entry.models.back())) {
        result.unavailable = parameter.name +
                             ": a change of 1e-3 changes the model's structure (a backlash of "
                             "zero, or a link the band makes rigid)";
        break;
      }
    }
    if (!result.unavailable.empty()) break;
    models.push_back(std::move(entry));
  }
  const std::unique_ptr<ModeIntegrator> integrator = MakeExactIntegrator(model, run);
  if (!result.unavailable.empty()) {
    result.simulation = RunHybrid(model, run, SolverOf(SolverKind::kExact).name, integrator.get());
    return result;
  }
  const double step = ExactStepLength(model, run);
  const int samples = OutputGrid(model.reduced_scene(), run).size();
  SensitivityPass pass(model, std::move(models), ExactScale(model, step), step, samples,
                       run.initial_state.has_value());
  result.simulation =
      RunHybrid(model, run, SolverOf(SolverKind::kExact).name, integrator.get(), &pass);
  if (!result.simulation.summary.success) {
    result.unavailable = "the run failed: " + result.simulation.summary.message;
  } else {
    result.unavailable = pass.unavailable();
  }
  if (result.unavailable.empty()) result.link_torque = pass.TakeOutputs();
  return result;
}

}  // namespace millkit::driveline
