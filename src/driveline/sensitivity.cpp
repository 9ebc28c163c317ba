// Forward sensitivities alongside the exact solver's run; see sensitivity.h for the equations.
//
// The run is the exact solver's (hybrid_driver.h): a HybridObserver is told every stop (leg end,
// event, breakpoint, output time) with the state there, and carries the sensitivities S = [s_1 …
// s_P] from stop to stop in the phase set of the leg. It works in the solver's scaled
// coordinates, ỹ = D⁻¹ z and S̃_j = σ_j D⁻¹ s_j (σ_j the parameter's magnitude), where
// M̃ = D⁻¹ M D has a norm near the fastest mode's rate and M̃_j = σ_j D⁻¹ M_j D is of the same size.
// The stops come from the solver as it runs, or from a run kept before (RecordedRun: its stops on
// a tape, replayed to the pass in the same order with the same values).
#include "millkit/driveline/sensitivity.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <type_traits>

#include "driveline/hybrid_driver.h"
#include "millkit/io/input_error.h"
#include "numerics/exponential_moments.h"

namespace millkit::driveline {
namespace {

// The stencil step, relative to the parameter's magnitude.
constexpr double kRelativeStep = 1e-3;
// Legs whose Taylor series would need more pieces (‖M̃‖∞ τ) take the matrix exponential instead.
constexpr double kMaxTaylorPieces = 16.0;
constexpr int kMaxTaylorTerms = 60;
// Taylor terms a full piece takes (θ = 1 to 1/4 ulp), for the caching rule.
constexpr double kTypicalTerms = 18.0;
constexpr double kEps = std::numeric_limits<double>::epsilon();
// A surface crossed at a rate below this fraction of its terms' size grazes: the event time's
// derivative is not defined.
constexpr double kGrazingRate = 1e-9;

// d/dp of a quantity from its values at p + offset·δ: Σ weight · f(p + offset·δ) / δ.
struct Stencil {
  std::vector<double> offsets;
  std::vector<double> weights;
};

// A model's coefficients (M, G, T, z(0), the forcing) are linear in a damping, a backlash, a gap
// position, a load and the bite time: one neighbour gives their derivative to roundoff,
// (f(p ± δ) − f(p)) / ±δ. They are not linear in a stiffness (the static twists T/c) or an inertia
// (1/J): four neighbours, ± δ and ± 2δ, error ≈ δ⁴ (one-sided, five points, at a bound).
bool CoefficientsLinearIn(SceneParameter::Kind kind) {
  using Kind = SceneParameter::Kind;
  return kind != Kind::kStiffness && kind != Kind::kInertia;
}

Stencil StencilFor(double value, double step, const ParameterRange& range, bool linear) {
  if (linear) {
    const double side = value + step > range.upper ? -1.0 : 1.0;
    return {{0, side}, {-side, side}};
  }
  const double reach = 2.0 * step;
  const bool below =
      value - reach < range.lower || (!range.lower_inclusive && value - reach <= range.lower);
  const bool above = value + reach > range.upper;
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
  // d/dp of a model quantity: Σ weight · f(model at offset) / δ; `quantity` is called with each
  // stencil model and its index k.
  template <typename Quantity>
  Eigen::MatrixXd Derivative(const Model& nominal, const Quantity& quantity) const {
    Eigen::MatrixXd sum;
    for (size_t k = 0; k < models.size(); ++k) {
      const Model& model = models[k] ? *models[k] : nominal;
      Eigen::MatrixXd value = quantity(model, k);
      if (k == 0)
        sum = stencil.weights[k] * value;
      else
        sum += stencil.weights[k] * value;
    }
    return sum / step;
  }
};

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// A non-zero entry of a sparse matrix (M̃ follows the line's tree: a few entries per row).
struct Entry {
  Eigen::Index row, col;
  double value;
};

// Everything the pass needs of one phase set. S̃ is n × P, row-major, so row i holds component
// i of every parameter's sensitivity; a stack of per-parameter matrices has row i P + j for
// parameter j's row i, and one product with a vector gives all of S̃'s update at once.
//
// Sink rows: a state ỹ_r' = −a_r ỹ_r + (other states) that no other row reads (its column of M̃
// and of every M̃_j is zero off the diagonal, and a_r > 0): a recorder low-pass. Over a piece
// of length τ the other rows are a Taylor polynomial Σ_k X_k (σ/τ)^k, and a sink row takes it
// exactly, ỹ_r(τ) = e^{−a_r τ} ỹ_r(0) + τ Σ_k g_k(−a_r τ) (M̃ X_k)_r
// (numerics/exponential_moments.h), so the series' pieces pay for the line's rates, not for the
// filter's (an 800 Hz low-pass is 5027 /s against a few hundred for the line).
struct PhaseSet {
  Eigen::MatrixXd m;                 // M (unscaled)
  Eigen::MatrixXd m_scaled;          // M̃
  std::vector<Entry> sparse;         // M̃'s non-zeros
  std::vector<Eigen::MatrixXd> m_p;  // M̃_j (empty when M_j = 0)
  // The system matrix of each parameter's stencil models (unscaled; empty for the nominal).
  std::vector<std::vector<Eigen::MatrixXd>> stencil_m;
  std::vector<Entry> sparse_p;      // the non-zeros of every M̃_j: row i P + j
  std::vector<Eigen::Index> sinks;  // the sink rows
  std::vector<double> sink_rate;    // a_r
  std::vector<Entry> core;          // M̃'s non-zeros in the other rows
  std::vector<Entry> core_p;        // sparse_p's in the other rows
  std::vector<Entry> sink_in;       // M̃'s non-zeros in sink rows off the diagonal: row r (sink)
  std::vector<Entry> sink_in_p;     // sparse_p's in sink rows: row r P + j
  Eigen::MatrixXd torque;           // T: reduced link torques = T z
  Eigen::MatrixXd torque_scaled;    // T D, per link factor: the recorded links' torques of ỹ
  Eigen::MatrixXd torque_p;         // T_j per link factor, stacked (row j links + l); built on
  bool has_torque_p = false;        // the first output in the phase set
  double norm = 0.0;  // of the other rows: ‖[M̃ M̃_j; 0 M̃]‖∞ <= ‖M̃‖∞ + max ‖M̃_j‖∞
  // Building the propagators over the step costs P exponentials of 2n × 2n; a full step then
  // costs 2 n² P instead of a Taylor series. They are built once the Taylor work of the full
  // steps so far exceeds the building's.
  double taylor_work = 0.0;
  bool cached = false;
  RowMatrix e;        // exp(M̃ h)
  Eigen::MatrixXd f;  // F̃_j(h), stacked
};

class SensitivityPass final : public HybridObserver {
 public:
  SensitivityPass(const Model& model, std::vector<ParameterModels> parameters,
                  const Eigen::VectorXd& scale, double step, int samples, bool given_state,
                  std::vector<int> links)
      : model_(model),
        parameters_(std::move(parameters)),
        d_(scale),
        d_inverse_(scale.cwiseInverse()),
        h_(step),
        n_(model.augmented_size()),
        nx_(model.state_size()),
        p_(static_cast<Eigen::Index>(parameters_.size())),
        given_state_(given_state),
        links_(std::move(links)) {
    const int links_out = static_cast<int>(links_.size());
    out_.assign(p_, Eigen::MatrixXd::Zero(samples, links_out));
    link_inverse_.resize(links_out);
    for (int l = 0; l < links_out; ++l) {
      link_inverse_[l] = 1.0 / model.shaft_factors().link[links_[l]];
    }
    surfaces_p_.resize(p_);
    for (int j = 0; j < p_; ++j) {
      surfaces_p_[j] = parameters_[j].Derivative(
          model_, [](const Model& m, size_t) -> Eigen::MatrixXd { return m.surfaces(); });
    }
  }

  const std::string& unavailable() const { return unavailable_; }
  std::vector<Eigen::MatrixXd> TakeOutputs() { return std::move(out_); }

  void Started(const Eigen::VectorXd& z0, const Phases& /*phases*/) override {
    s_.setZero(n_, p_);
    s_term_.setZero(n_, p_);
    s_next_.setZero(n_, p_);
    y_.setZero(n_);
    y_term_.setZero(n_);
    y_next_.setZero(n_);
    for (int j = 0; j < p_; ++j) {
      const Eigen::VectorXd ds = parameters_[j].Derivative(
          model_, [](const Model& m, size_t) -> Eigen::MatrixXd { return m.InitialState(); });
      Eigen::VectorXd s = ds;
      // A given initial state (options.initial_state) holds x whatever the parameters.
      if (given_state_) s.head(model_.state_size()).setZero();
      SetS(j, s);
    }
    z_ = z0;
    rest_ = nullptr;
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
    rest_ = nullptr;
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
            parameter.Derivative(model_, [&](const Model& m, size_t) -> Eigen::MatrixXd {
              Eigen::VectorXd right = z;
              m.SetForcing(breakpoint, &right);
              return right.tail(2 * nw);
            });
        s.tail(2 * nw) = forcing;
      }
      SetS(j, s);
    }
    z_ = z;
    rest_ = nullptr;
  }

  void Recorded(int k, const Phases& phases) override {
    if (!unavailable_.empty()) return;
    PhaseSet& data = Data(phases);
    const auto links = static_cast<Eigen::Index>(links_.size());
    if (!data.has_torque_p) {
      data.torque_p.resize(links * p_, n_);
      for (int j = 0; j < p_; ++j) {
        data.torque_p.middleRows(j * links, links) =
            link_inverse_.asDiagonal() *
            parameters_[j].Derivative(model_, [&](const Model& m, size_t k) {
              const Eigen::MatrixXd& system =
                  data.stencil_m[j][k].size() != 0 ? data.stencil_m[j][k] : data.m;
              return Eigen::MatrixXd(m.LinkTorqueRows(phases, system)(links_, Eigen::all));
            });
      }
      data.has_torque_p = true;
    }
    // ∂τ/∂p_j = T s_j + T_j z, s_j = D S̃_j / σ_j.
    torque_scratch_.noalias() = data.torque_scaled.lazyProduct(s_);
    stacked_scratch_.noalias() = data.torque_p * z_;
    for (int j = 0; j < p_; ++j) {
      const double inverse_magnitude = 1.0 / parameters_[j].magnitude;
      for (Eigen::Index l = 0; l < links; ++l) {
        out_[j](k, l) = torque_scratch_(l, j) * inverse_magnitude + stacked_scratch_[j * links + l];
      }
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
    for (int i = 0; i < n_; ++i) {
      for (int c = 0; c < n_; ++c) {
        if (data.m_scaled(i, c) != 0.0) data.sparse.push_back({i, c, data.m_scaled(i, c)});
      }
    }
    data.m_p.resize(p_);
    data.stencil_m.resize(p_);
    for (int j = 0; j < p_; ++j) {
      data.stencil_m[j].resize(parameters_[j].models.size());
      const Eigen::MatrixXd mp =
          parameters_[j].Derivative(model_, [&](const Model& m, size_t k) -> Eigen::MatrixXd {
            if (&m == &model_) return data.m;
            data.stencil_m[j][k] = m.SystemMatrix(phases);
            return data.stencil_m[j][k];
          });
      if (mp.cwiseAbs().maxCoeff() == 0.0) continue;
      data.m_p[j] = parameters_[j].magnitude * (d_inverse_.asDiagonal() * mp * d_.asDiagonal());
      for (int i = 0; i < n_; ++i) {
        for (int c = 0; c < n_; ++c) {
          if (data.m_p[j](i, c) != 0.0) data.sparse_p.push_back({i * p_ + j, c, data.m_p[j](i, c)});
        }
      }
    }
    SplitSinks(&data);
    data.torque = model_.LinkTorqueRows(phases, data.m);
    data.torque_scaled =
        link_inverse_.asDiagonal() * data.torque(links_, Eigen::all) * d_.asDiagonal();
    current_ = &data;
    return data;
  }

  // The sink rows of a phase set (see PhaseSet), its non-zeros split between them and the other
  // rows, and the other rows' norm. No parameter moves a low-pass's rate; the stencil leaves
  // roundoff on a sink's own entry of M̃_j (the rate's stencil sum), which is dropped.
  void SplitSinks(PhaseSet* data) const {
    constexpr double kRoundoff = 1e-6;  // relative to the rate; a rate's sensitivity is O(1)
    // Whether a column is read off its diagonal (by M̃, or by M̃_j beyond the roundoff).
    std::vector<char> read(n_, 0);
    for (const Entry& entry : data->sparse) read[entry.col] |= entry.col != entry.row;
    for (const Entry& entry : data->sparse_p) {
      read[entry.col] |=
          entry.row / p_ != entry.col ||
          !(std::abs(entry.value) <= -kRoundoff * data->m_scaled(entry.col, entry.col));
    }
    std::vector<Eigen::Index> sink_of(n_, -1);
    for (Eigen::Index i = 0; i < nx_; ++i) {
      const double rate = -data->m_scaled(i, i);
      if (!(rate > 0.0) || read[i]) continue;
      sink_of[i] = static_cast<Eigen::Index>(data->sinks.size());
      data->sinks.push_back(i);
      data->sink_rate.push_back(rate);
      for (Eigen::MatrixXd& m_p : data->m_p) {
        if (m_p.size() != 0) m_p(i, i) = 0.0;
      }
    }
    if (!data->sinks.empty()) {
      std::erase_if(data->sparse_p, [&](const Entry& entry) { return sink_of[entry.col] >= 0; });
    }
    Eigen::VectorXd row_norm = Eigen::VectorXd::Zero(n_),
                    row_norm_p = Eigen::VectorXd::Zero(n_ * p_);
    for (const Entry& entry : data->sparse) {
      const Eigen::Index sink = sink_of[entry.row];
      if (sink < 0) {
        data->core.push_back(entry);
        row_norm[entry.row] += std::abs(entry.value);
      } else if (entry.col != entry.row) {
        data->sink_in.push_back({sink, entry.col, entry.value});
      }
    }
    for (const Entry& entry : data->sparse_p) {
      const Eigen::Index sink = sink_of[entry.row / p_];
      if (sink < 0) {
        data->core_p.push_back(entry);
        row_norm_p[entry.row] += std::abs(entry.value);
      } else {
        data->sink_in_p.push_back({sink * p_ + entry.row % p_, entry.col, entry.value});
      }
    }
    data->norm = row_norm.maxCoeff() + (p_ > 0 ? row_norm_p.maxCoeff() : 0.0);
  }

  // For each sink row r of `data` over a piece of length τ: e^{−a_r τ} into decay[r] and
  // τ g_k(−a_r τ), k = 0 … terms, into weights[r (terms + 1) + k].
  static void SinkWeights(const PhaseSet& data, double tau, int terms, std::vector<double>* decay,
                          std::vector<double>* weights) {
    const size_t sinks = data.sinks.size();
    decay->resize(sinks);
    weights->resize(sinks * (terms + 1));
    for (size_t r = 0; r < sinks; ++r) {
      double* g = weights->data() + r * (terms + 1);
      if (r > 0 && data.sink_rate[r] == data.sink_rate[r - 1]) {  // two channels' equal filters
        (*decay)[r] = (*decay)[r - 1];
        std::copy(g - (terms + 1), g, g);
        continue;
      }
      const double z = -data.sink_rate[r] * tau;
      (*decay)[r] = std::exp(z);
      numerics::ExponentialMoments(z, terms, g);
      for (int k = 0; k <= terms; ++k) g[k] *= tau;
    }
  }

  // exp(M̃ τ) and F̃_j(τ) (stacked), the blocks of exp([M̃ M̃_j; 0 M̃] τ), for every j at once:
  // one Taylor series over σ = τ / 2^s with θ = ‖[M̃ M̃_j; 0 M̃]‖∞ σ <= 1/2 (the other rows'), on
  // the non-zeros of M̃ and M̃_j,
  //   A_k = (σ/k) M̃ A_{k−1},  B_{j,k} = (σ/k) (M̃ B_{j,k−1} + M̃_j A_{k−1}),  A_0 = I, B_{j,0} = 0,
  // E = Σ A_k, F_j = Σ B_{j,k} (the top right block of the k-th power is Σ_i M̃^i M̃_j M̃^(k−1−i)),
  // the sink rows from the terms' other rows with the weights of SinkWeights, then s squarings of
  // the block matrix: F_j ← E F_j + F_j E, E ← E².
  void Exponentials(const PhaseSet& data, double tau, RowMatrix* e, Eigen::MatrixXd* f) const {
    const double norm = data.norm * tau;
    const int squarings =
        norm > 0.5 && std::isfinite(norm) ? static_cast<int>(std::ceil(std::log2(norm / 0.5))) : 0;
    const double sigma = std::ldexp(tau, -squarings);
    const double theta = data.norm * sigma;
    // Terms until the next one's bound θ^(k+1)/(k+1)! drops below 1/4 ulp.
    int terms = 1;
    for (double bound = theta * theta / 2; terms < kMaxTaylorTerms && bound > 0.25 * kEps;) {
      ++terms;
      bound *= theta / (terms + 1);
    }
    std::vector<double> decay, weights;
    SinkWeights(data, sigma, terms, &decay, &weights);
    const size_t sinks = data.sinks.size();
    std::vector<int> moved;                        // the parameters with M̃_j ≠ 0
    std::vector<std::vector<Entry>> entries;       // the non-zeros of each such M̃_j, other rows
    std::vector<std::vector<Entry>> sink_entries;  // and in sink rows (row r)
    std::vector<Eigen::Index> sink_of(n_, -1);
    for (size_t r = 0; r < sinks; ++r) sink_of[data.sinks[r]] = static_cast<Eigen::Index>(r);
    for (int j = 0; j < p_; ++j) {
      if (data.m_p[j].size() == 0) continue;
      moved.push_back(j);
      entries.emplace_back();
      sink_entries.emplace_back();
      for (int c = 0; c < n_; ++c) {
        for (int i = 0; i < n_; ++i) {
          const double value = data.m_p[j](i, c);
          if (value == 0.0) continue;
          if (sink_of[i] < 0) {
            entries.back().push_back({i, c, value});
          } else {
            sink_entries.back().push_back({sink_of[i], c, value});
          }
        }
      }
    }
    const size_t count = moved.size();
    // Row-major: a non-zero (i, c) adds a multiple of row c to row i.
    RowMatrix a = RowMatrix::Identity(n_, n_), next_a(n_, n_);
    RowMatrix sum_a = a;
    std::vector<RowMatrix> b(count, RowMatrix::Zero(n_, n_)), sum_b = b;
    RowMatrix next_b(n_, n_);
    const auto sink_count = static_cast<Eigen::Index>(sinks);
    RowMatrix sink_a = RowMatrix::Zero(sink_count, n_);
    std::vector<RowMatrix> sink_b(count, RowMatrix::Zero(sink_count, n_));
    for (int k = 0;; ++k) {
      // The sink rows take term k of the others.
      for (const Entry& entry : data.sink_in) {
        const double w = weights[entry.row * (terms + 1) + k] * entry.value;
        sink_a.row(entry.row) += w * a.row(entry.col);
        for (size_t m = 0; m < count; ++m) sink_b[m].row(entry.row) += w * b[m].row(entry.col);
      }
      for (size_t m = 0; m < count; ++m) {
        for (const Entry& entry : sink_entries[m]) {
          sink_b[m].row(entry.row) +=
              (weights[entry.row * (terms + 1) + k] * entry.value) * a.row(entry.col);
        }
      }
      if (k == terms) break;
      const double factor = sigma / (k + 1);
      for (size_t m = 0; m < count; ++m) {
        next_b.setZero();
        for (const Entry& entry : data.core) {
          next_b.row(entry.row) += (factor * entry.value) * b[m].row(entry.col);
        }
        for (const Entry& entry : entries[m]) {
          next_b.row(entry.row) += (factor * entry.value) * a.row(entry.col);
        }
        b[m].swap(next_b);
        sum_b[m] += b[m];
      }
      next_a.setZero();
      for (const Entry& entry : data.core) {
        next_a.row(entry.row) += (factor * entry.value) * a.row(entry.col);
      }
      a.swap(next_a);
      sum_a += a;
    }
    for (size_t r = 0; r < sinks; ++r) {
      const Eigen::Index row = data.sinks[r];
      sum_a.row(row) = sink_a.row(static_cast<Eigen::Index>(r));
      sum_a(row, row) = decay[r];
      for (size_t m = 0; m < count; ++m) {
        sum_b[m].row(row) = sink_b[m].row(static_cast<Eigen::Index>(r));
      }
    }
    for (int q = 0; q < squarings; ++q) {
      for (size_t m = 0; m < count; ++m) {
        next_b.noalias() = sum_a * sum_b[m];
        next_b.noalias() += sum_b[m] * sum_a;
        sum_b[m].swap(next_b);
      }
      next_a.noalias() = sum_a * sum_a;
      sum_a.swap(next_a);
    }
    *e = sum_a;
    f->setZero(n_ * p_, n_);
    for (size_t m = 0; m < count; ++m) (*f)(Eigen::seqN(moved[m], n_, p_), Eigen::all) = sum_b[m];
  }

  // S̃ ← E S̃ + [F̃_j ỹ]: the propagators applied. The inputs depend neither on the state nor
  // on the parameters within a leg, so E's input rows are [0 E_ww] and F̃_j's are zero: only the
  // state rows take the full products (n × n by n × P and nP × n by n, the floor of the pass).
  // Row i of E S̃ is Σ_k E_ik S̃_k in k order (S̃_k a contiguous row of P), every row's sum
  // taking its k-th term before any takes its k + 1-th: the rows' sums are independent of each
  // other, where one row's are a chain.
  void Apply(const RowMatrix& e, const Eigen::MatrixXd& f) {
    const Eigen::Index p = p_;
    const auto row_times = [&](Eigen::Index i, Eigen::Index k, bool first) {
      const double value = e(i, k);
      double* to = s_next_.data() + i * p;
      const double* from = s_.data() + k * p;
      if (first) {
        for (Eigen::Index j = 0; j < p; ++j) to[j] = value * from[j];
      } else {
        for (Eigen::Index j = 0; j < p; ++j) to[j] += value * from[j];
      }
    };
    // The state rows read every row of S̃; an input row reads only the inputs.
    for (Eigen::Index i = 0; i < n_; ++i) row_times(i, i < nx_ ? 0 : nx_, true);
    for (Eigen::Index k = 1; k < n_; ++k) {
      for (Eigen::Index i = 0; i < nx_; ++i) row_times(i, k, false);
      if (k <= nx_) continue;
      for (Eigen::Index i = nx_; i < n_; ++i) row_times(i, k, false);
    }
    Eigen::Map<Eigen::VectorXd>(s_next_.data(), nx_ * p_).noalias() += f.topRows(nx_ * p_) * y_;
    s_.swap(s_next_);
  }

  // Whether [ỹ; S̃]' = [M̃ ỹ; M̃ S̃ + M̃_j ỹ] is zero in this phase set (s_next_ holds the second
  // block): a line running steadily before the bite (no relative motion, no load yet) and
  // sensitivities that do not move it (a gap's position within its play). Nothing moves over a
  // leg then. Remembered for the same phase set and state until a jump changes S̃. The first
  // product, M̃ ỹ, decides almost every leg that moves, for a few multiply-adds.
  bool AtRest(const PhaseSet& data) {
    if (rest_ == &data && z_ == rest_z_) return true;
    rest_ = nullptr;
    y_next_.setZero();
    for (const Entry& entry : data.sparse) y_next_[entry.row] += entry.value * y_[entry.col];
    if (!y_next_.isZero(0.0)) return false;
    s_next_.setZero();
    double* next = s_next_.data();
    for (const Entry& entry : data.sparse_p) next[entry.row] += entry.value * y_[entry.col];
    for (const Entry& entry : data.sparse)
      s_next_.row(entry.row) += entry.value * s_.row(entry.col);
    if (!s_next_.isZero(0.0)) return false;
    rest_ = &data;
    rest_z_ = z_;
    return true;
  }

  void Propagate(PhaseSet& data, double tau) {
    if (tau <= 0.0) return;
    y_.noalias() = d_inverse_.asDiagonal() * z_;
    if (AtRest(data)) return;
    const double pieces = std::ceil(data.norm * tau);
    const bool full_step = std::abs(tau - h_) <= 1e-10 * h_;
    if (full_step && !data.cached) {
      // Work in multiply-adds: a Taylor term against one exponential of 2n × 2n (≈ 20 (2n)³).
      const double n = n_;
      data.taylor_work +=
          std::max(pieces, 1.0) * kTypicalTerms *
          static_cast<double>((data.sparse.size() + 1) * (p_ + 1) + data.sparse_p.size());
      const double build = 0.25 * 8.0 * n * n * n * (1.0 + static_cast<double>(p_));
      if (pieces > kMaxTaylorPieces || data.taylor_work > build) {
        Exponentials(data, h_, &data.e, &data.f);
        data.cached = true;
      }
    }
    if (full_step && data.cached) {
      Apply(data.e, data.f);
      return;
    }
    if (pieces > kMaxTaylorPieces) {
      RowMatrix e;
      Eigen::MatrixXd f;
      Exponentials(data, tau, &e, &f);
      Apply(e, f);
      return;
    }
    // The Taylor series of [ỹ; S̃]' = [M̃ ỹ; M̃ S̃ + M̃_j ỹ] in pieces with θ = ‖·‖∞ dt <= 1 (the
    // rows but the sinks), on the non-zeros of M̃ and M̃_j, to the term where θ^(K+1)/(K+1)!
    // drops below 1/4 ulp; the sink rows take every term of the others (SinkWeights).
    const int count = std::max(1, static_cast<int>(pieces));
    const double dt = tau / count;
    const double theta = data.norm * dt;
    int terms = 1;
    for (double bound = theta; terms < kMaxTaylorTerms && bound > 0.25 * kEps; ++terms) {
      bound *= theta / (terms + 1);
    }
    // Legs of one length (the full steps before caching) in phase sets of the same filters
    // share their weights: kept from the last call.
    if (dt != weights_tau_ || terms != weights_terms_ || data.sink_rate != weights_rates_) {
      SinkWeights(data, dt, terms, &decay_, &weights_);
      weights_tau_ = dt;
      weights_terms_ = terms;
      weights_rates_ = data.sink_rate;
    }
    const auto sinks = static_cast<Eigen::Index>(data.sinks.size());
    for (int piece = 0; piece < count; ++piece) {
      y_term_ = y_;
      s_term_ = s_;
      sink_y_.setZero(sinks);
      sink_s_.setZero(sinks, p_);
      for (int k = 0;; ++k) {
        for (const Entry& entry : data.sink_in) {
          const double w = weights_[entry.row * (terms + 1) + k] * entry.value;
          sink_y_[entry.row] += w * y_term_[entry.col];
          sink_s_.row(entry.row) += w * s_term_.row(entry.col);
        }
        double* sink_next = sink_s_.data();
        for (const Entry& entry : data.sink_in_p) {
          sink_next[entry.row] +=
              weights_[(entry.row / p_) * (terms + 1) + k] * entry.value * y_term_[entry.col];
        }
        if (k == terms) break;
        const double factor = dt / (k + 1);
        s_next_.setZero();
        y_next_.setZero();
        double* next = s_next_.data();
        const double* term = s_term_.data();
        for (const Entry& entry : data.core) {
          const double value = factor * entry.value;
          double* to = next + static_cast<std::ptrdiff_t>(entry.row) * p_;
          const double* from = term + static_cast<std::ptrdiff_t>(entry.col) * p_;
          for (int j = 0; j < p_; ++j) to[j] += value * from[j];
          y_next_[entry.row] += value * y_term_[entry.col];
        }
        for (const Entry& entry : data.core_p) {
          next[entry.row] += factor * entry.value * y_term_[entry.col];
        }
        s_term_.swap(s_next_);
        y_term_.swap(y_next_);
        y_ += y_term_;
        s_ += s_term_;
      }
      for (Eigen::Index r = 0; r < sinks; ++r) {
        const Eigen::Index row = data.sinks[r];
        y_[row] = decay_[r] * y_[row] + sink_y_[r];
        s_.row(row) = decay_[r] * s_.row(row) + sink_s_.row(r);
      }
    }
  }

  const Model& model_;
  std::vector<ParameterModels> parameters_;
  Eigen::VectorXd d_, d_inverse_;
  double h_;
  Eigen::Index n_, nx_, p_;  // augmented size, state size, parameters
  bool given_state_;
  std::vector<Eigen::MatrixXd> surfaces_p_;  // G_j (unscaled)
  std::map<Phases, PhaseSet> cache_;
  PhaseSet* current_ = nullptr;     // the phase set of the latest leg
  const PhaseSet* rest_ = nullptr;  // the phase set found at rest (AtRest) with state rest_z_
  Eigen::VectorXd rest_z_;
  RowMatrix s_;                   // S̃
  Eigen::VectorXd z_;             // the state at the latest stop
  std::vector<int> links_;        // the scene links whose torques' sensitivities are recorded
  Eigen::VectorXd link_inverse_;  // 1 / each such link's shaft factor
  // Scratch of Propagate and Recorded.
  Eigen::VectorXd y_, y_term_, y_next_, stacked_scratch_, sink_y_;
  RowMatrix s_term_, s_next_, sink_s_;
  std::vector<double> decay_, weights_;  // SinkWeights at (weights_tau_, weights_terms_) for
  double weights_tau_ = -1.0;            // sinks of rates weights_rates_ (Propagate)
  int weights_terms_ = -1;
  std::vector<double> weights_rates_;
  Eigen::MatrixXd torque_scratch_;
  std::vector<Eigen::MatrixXd> out_;
  std::string unavailable_;
};

// Every call a run makes to its observer, kept in order to be made again to another observer
// (RecordedRun): the states in one array, the phases as they came. A tape that outgrows its budget
// (a run of very many events, a very long record) is dropped and keeps nothing more.
class StopTape final : public HybridObserver {
 public:
  explicit StopTape(size_t budget_bytes) : budget_(budget_bytes) {}

  // Whether every call was kept.
  bool complete() const { return !dropped_; }

  void Started(const Eigen::VectorXd& z0, const Phases& phases) override {
    if (!Room()) return;
    calls_.push_back(Call::kStarted);
    Keep(z0);
    phases_.push_back(phases);
  }
  void LegEnded(double elapsed, const Phases& phases, const Eigen::VectorXd& z,
                bool blind) override {
    if (!Room()) return;
    calls_.push_back(blind ? Call::kBlindLeg : Call::kLeg);
    numbers_.push_back(elapsed);
    phases_.push_back(phases);
    Keep(z);
  }
  void Switched(const Phases& before, const Phases& after,
                const std::vector<Model::KnownSide>& crossed) override {
    if (!Room()) return;
    calls_.push_back(Call::kSwitched);
    phases_.push_back(before);
    phases_.push_back(after);
    crossed_.push_back(crossed);
  }
  void BreakpointApplied(double breakpoint, const Eigen::VectorXd& z) override {
    if (!Room()) return;
    calls_.push_back(Call::kBreakpoint);
    numbers_.push_back(breakpoint);
    Keep(z);
  }
  void Recorded(int k, const Phases& phases) override {
    if (!Room()) return;
    calls_.push_back(Call::kRecorded);
    samples_.push_back(k);
    phases_.push_back(phases);
  }

  void Replay(HybridObserver* observer) const {
    size_t number = 0, phase = 0, state = 0, size = 0, crossed = 0, sample = 0;
    Eigen::VectorXd z;
    const auto next_state = [&]() -> const Eigen::VectorXd& {
      z = Eigen::Map<const Eigen::VectorXd>(states_.data() + state, sizes_[size]);
      state += static_cast<size_t>(sizes_[size++]);
      return z;
    };
    for (const Call call : calls_) {
      switch (call) {
        case Call::kStarted: {
          const Eigen::VectorXd& z0 = next_state();
          observer->Started(z0, phases_[phase++]);
          break;
        }
        case Call::kLeg:
        case Call::kBlindLeg: {
          const double elapsed = numbers_[number++];
          const Phases& phases = phases_[phase++];
          observer->LegEnded(elapsed, phases, next_state(), call == Call::kBlindLeg);
          break;
        }
        case Call::kSwitched:
          observer->Switched(phases_[phase], phases_[phase + 1], crossed_[crossed++]);
          phase += 2;
          break;
        case Call::kBreakpoint: {
          const double breakpoint = numbers_[number++];
          observer->BreakpointApplied(breakpoint, next_state());
          break;
        }
        case Call::kRecorded:
          observer->Recorded(samples_[sample++], phases_[phase++]);
          break;
      }
    }
  }

 private:
  enum class Call : char { kStarted, kLeg, kBlindLeg, kSwitched, kBreakpoint, kRecorded };
  void Keep(const Eigen::VectorXd& z) {
    states_.insert(states_.end(), z.data(), z.data() + z.size());
    sizes_.push_back(z.size());
  }
  // False once the tape is over its budget (the states, and about 64 bytes a call for the rest):
  // then it is dropped.
  bool Room() {
    if (dropped_) return false;
    if (states_.size() * sizeof(double) + calls_.size() * 64 <= budget_) return true;
    dropped_ = true;
    const auto release = [](auto* v) { std::remove_reference_t<decltype(*v)>().swap(*v); };
    release(&calls_);
    release(&numbers_);
    release(&states_);
    release(&sizes_);
    release(&phases_);
    release(&crossed_);
    release(&samples_);
    return false;
  }

  std::vector<Call> calls_;
  std::vector<double> numbers_;  // leg lengths and breakpoints, in call order
  std::vector<double> states_;   // every state, one after the other
  std::vector<Eigen::Index> sizes_;
  std::vector<Phases> phases_;
  std::vector<std::vector<Model::KnownSide>> crossed_;
  std::vector<int> samples_;
  size_t budget_;
  bool dropped_ = false;
};

// The sensitivities of a run of `model` with options `run` (validated, exact solver): the solver
// runs with the pass attached, or (`kept`, with its `result`) the pass follows a kept run.
SensitivityResult Sensitivities(const Model& model, const SimulationOptions& run,
                                const std::vector<SceneParameter>& parameters,
                                const std::vector<int>& links, const StopTape* kept,
                                const SimulationResult* kept_result) {
  SensitivityResult result;
  const Scene& scene = model.scene();
  const int scene_links = static_cast<int>(scene.links.size());
  for (const int l : links) {
    if (l < 0 || l >= scene_links) {
      throw InputError("SimulateWithSensitivities: link index " + std::to_string(l) +
                       " is not one of the scene's " + std::to_string(scene_links) + " links");
    }
  }
  std::vector<int> recorded = links;
  if (recorded.empty()) {
    recorded.resize(scene_links);
    for (int l = 0; l < scene_links; ++l) recorded[l] = l;
  }
  std::vector<ParameterModels> models;
  for (const SceneParameter& parameter : parameters) {
    ParameterModels entry;
    entry.parameter = parameter;
    const double value = parameter.Get(scene);
    entry.magnitude = Magnitude(parameter, scene, value);
    entry.step = kRelativeStep * entry.magnitude;
    entry.bite_time = parameter.kind == SceneParameter::Kind::kBiteTime;
    entry.stencil = StencilFor(value, entry.step, PhysicalRange(parameter.kind),
                               CoefficientsLinearIn(parameter.kind));
    for (const double offset : entry.stencil.offsets) {
      if (offset == 0.0) {
        entry.models.push_back(nullptr);
        continue;
      }
      Scene perturbed = scene;
      parameter.Set(value + offset * entry.step, &perturbed);
      try {
        entry.models.push_back(
            std::make_unique<Model>(std::move(perturbed), Model::Use::kCoefficients));
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
  // The run, with `observer` told every stop.
  const auto run_along = [&](HybridObserver* observer) {
    if (kept != nullptr) {
      if (observer != nullptr) kept->Replay(observer);
      return *kept_result;
    }
    const std::unique_ptr<ModeIntegrator> integrator = MakeExactIntegrator(model, run);
    return RunHybrid(model, run, SolverOf(SolverKind::kExact).name, integrator.get(), observer);
  };
  if (!result.unavailable.empty()) {
    result.simulation = run_along(nullptr);
    return result;
  }
  const double step = ExactStepLength(model, run);
  const int samples = OutputGrid(model.reduced_scene(), run).size();
  SensitivityPass pass(model, std::move(models), ExactScale(model, step), step, samples,
                       run.initial_state.has_value(), std::move(recorded));
  result.simulation = run_along(&pass);
  if (!result.simulation.summary.success) {
    result.unavailable = "the run failed: " + result.simulation.summary.message;
  } else {
    result.unavailable = pass.unavailable();
  }
  if (result.unavailable.empty()) result.link_torque = pass.TakeOutputs();
  return result;
}

}  // namespace

SensitivityResult SimulateWithSensitivities(const Scene& scene,
                                            const std::vector<SceneParameter>& parameters,
                                            const SimulationOptions& options,
                                            const std::vector<int>& links) {
  SimulationOptions run = options;
  run.solver = SolverKind::kExact;
  run.keep_samples = true;
  run.sample_sink = nullptr;
  const Model model(scene);
  run.Validate(model.scene());
  return Sensitivities(model, run, parameters, links, nullptr, nullptr);
}

struct RecordedRun::Kept {
  Kept(const Scene& scene, const SimulationOptions& given, size_t budget_bytes)
      : model(scene), options(given), stops(budget_bytes) {}
  Model model;
  SimulationOptions options;
  SimulationResult result;
  StopTape stops;
};

RecordedRun::RecordedRun() = default;
RecordedRun::~RecordedRun() = default;
RecordedRun::RecordedRun(RecordedRun&&) noexcept = default;
RecordedRun& RecordedRun::operator=(RecordedRun&&) noexcept = default;

RecordedRun::RecordedRun(const Scene& scene, const SimulationOptions& options, size_t budget_bytes)
    : kept_(std::make_unique<Kept>(scene, options, budget_bytes)) {
  Kept& kept = *kept_;
  kept.options.solver = SolverKind::kExact;
  kept.options.Validate(kept.model.scene());
  const std::unique_ptr<ModeIntegrator> integrator = MakeExactIntegrator(kept.model, kept.options);
  kept.result = RunHybrid(kept.model, kept.options, SolverOf(SolverKind::kExact).name,
                          integrator.get(), &kept.stops);
  // The caller's callbacks belong to the run that is over.
  kept.options.sample_sink = nullptr;
  kept.options.progress = nullptr;
}

bool RecordedRun::stops_kept() const { return kept_ != nullptr && kept_->stops.complete(); }

const SimulationResult& RecordedRun::result() const {
  if (kept_ == nullptr) throw std::logic_error("RecordedRun::result: no run is kept");
  return kept_->result;
}

SensitivityResult SimulateWithSensitivities(const RecordedRun& run,
                                            const std::vector<SceneParameter>& parameters,
                                            const std::vector<int>& links) {
  if (run.empty()) throw std::logic_error("SimulateWithSensitivities: no run is kept");
  const RecordedRun::Kept& kept = *run.kept_;
  if (!kept.stops.complete()) {  // the run again, with the pass
    return Sensitivities(kept.model, kept.options, parameters, links, nullptr, nullptr);
  }
  return Sensitivities(kept.model, kept.options, parameters, links, &kept.stops, &kept.result);
}

}  // namespace millkit::driveline
