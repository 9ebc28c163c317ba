// Event-exact piecewise-linear solver (issue 2). See simulation.h for the contract.
//
// Within one phase set the augmented ODE z' = M z is autonomous and linear. The solver carries z
// and its derivative v = z' and steps in increment form (numerics/exp_phi.h):
//   z(t + τ) = z + Φ(τ) v,   v(t + τ) = S(τ) v,   S = exp(M τ),  Φ = ∫₀^τ exp(M s) ds,
// exact to roundoff, and exact outright at rest (v = 0): a link resting on its back flank at zero
// torque stays on the switching surface, where a stepped exp(M h) z drifts across it by roundoff
// and counts events that CVODE does not see.
//  - A full output step of a phase set already stepped kStepsBeforeCaching times uses the cached
//    [Φ; S] for the sample interval h: one small product per step (numerics/small_matvec.h), and
//    one more for the surfaces and link torques, [R; T] z.
//  - Every other step (to an event, a breakpoint, an irregular output time, or in a phase set seen
//    only briefly) sums the Taylor series of v, v(t + s dt) = Σ u_k s^k, u_k = (M dt)^k v / k!,
//    over pieces dt with ‖M dt‖∞ <= 1; z follows by integrating it term by term.
// Events: a watched surface g = r·z changes side within a step. Each step first bounds every
// watched surface from its values at the two ends: the chord is off g by at most max|g''| τ²/8,
// |g''| = |r M v| <= |r| |M| 1 · e^{‖M‖∞ τ} ‖v(t)‖∞. Those it does not clear are bounded from
// their values and slopes: with u = s/τ, the cubic Hermite interpolant differs from g by at most
// max|g⁗| τ⁴ u²(1 − u)²/4!, |g⁗| <= |r| |M|³ 1 · e^{‖M‖∞ τ} ‖v(t)‖∞. A surface that the motion
// cannot reach (no path in M's graph from a moving component to the surface's) stays put.
// Only a surface whose bound reaches below zero is looked at exactly: on the step's Taylor series
// it is a polynomial in s, searched left to right with the same bound on halved intervals, and its
// first root is located by safeguarded Newton to a few ulps of time.
// Everything runs in scaled coordinates y = D⁻¹ z, D = diag(typical magnitudes): D⁻¹ M D has a
// norm near the fastest mode's frequency, where the raw M mixes units (N·m/rad over kg·m² next
// to 1) and would need many more Taylor terms.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include "driveline/output_recorder.h"
#include "driveline/simulation.h"
#include "numerics/exp_phi.h"
#include "numerics/small_matvec.h"

namespace millkit::driveline {
namespace {

using numerics::PaddedMatrix;

// The solver's hot paths, compiled for x86-64-v3 (AVX2, FMA) as well as the baseline and chosen
// at load time: their short loops over a dozen components vectorise 4 wide. (Results differ
// between the two in the last bits, FMA.)
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define MILLKIT_HOT __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define MILLKIT_HOT
#endif

constexpr double kEps = std::numeric_limits<double>::epsilon();
// A surface that dips past zero by less than this fraction of its typical magnitude (times the
// state's size in scaled units) has not crossed: roundoff, or a graze.
constexpr double kCrossingTolerance = 1e-13;
// Events closer in time than this many ulps of t count as "not advancing"; roots are located to
// this resolution.
constexpr double kStallUlps = 64.0;
constexpr int kMaxStalledEvents = 64;
constexpr int kMaxRootIterations = 100;
constexpr int kMaxTaylorTerms = 60;
// Building [Φ; S] costs about as much as 10 Taylor steps; phase sets that last a few samples
// (contact transients, brief separations) never pay it.
constexpr long kStepsBeforeCaching = 8;
// Halvings of one polynomial before a surface that keeps within its bound is called a graze.
constexpr int kMaxSearchDepth = 60;

// Typical magnitude of each component of z: states from the model, forcing from the sources.
Eigen::VectorXd AugmentedScale(const Model& model) {
  const int nx = model.state_size(), nw = model.forcing_size();
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(model.augmented_size());
  scale.head(nx) = model.StateScale();
  const auto& torques = model.reduced_scene().torques;
  for (int s = 0; s < nw - 1; ++s) {
    double value = 0.0, slope = 0.0;
    const auto& source = torques[s];
    for (size_t i = 0; i < source.times_s.size(); ++i) {
      value = std::max(value, std::abs(source.values_Nm[i]));
      if (i > 0 && source.times_s[i] > source.times_s[i - 1]) {
        slope = std::max(slope, std::abs(source.values_Nm[i] - source.values_Nm[i - 1]) /
                                    (source.times_s[i] - source.times_s[i - 1]));
      }
    }
    scale[nx + 1 + s] = std::max(value, 1.0);
    scale[nx + nw + 1 + s] = std::max(slope, 1.0);
  }
  return scale;
}

// The step whose propagator is cached per phase set: the scene's sample interval, or for given
// output times the median gap (an oscillogram's sampling interval).
double CachedStepLength(const Scene& scene, const SimulationOptions& options,
                        const std::vector<double>& times) {
  if (!options.output_times || times.size() < 2) return 1.0 / scene.sample_rate_Hz;
  std::vector<double> gaps(times.size() - 1);
  for (size_t k = 1; k < times.size(); ++k) gaps[k - 1] = times[k] - times[k - 1];
  std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 2, gaps.end());
  return gaps[gaps.size() / 2];
}

// A plain loop: std::copy of a dozen doubles becomes a call to memmove.
inline void Copy(const double* __restrict from, int n, double* __restrict to) {
  for (int i = 0; i < n; ++i) to[i] = from[i];
}

// Minimum of k0 + k1 u + k2 u² + k3 u³ over [lo, hi].
double CubicMinimum(double k0, double k1, double k2, double k3, double lo, double hi) {
  auto f = [&](double u) { return k0 + u * (k1 + u * (k2 + u * k3)); };
  double lowest = std::min(f(lo), f(hi));
  auto consider = [&](double u) {
    if (u > lo && u < hi) lowest = std::min(lowest, f(u));
  };
  // f'(u) = k1 + 2 k2 u + 3 k3 u²; stable roots of the quadratic.
  const double qa = 3.0 * k3, qb = 2.0 * k2, qc = k1;
  if (qa == 0.0) {
    if (qb != 0.0) consider(-qc / qb);
  } else {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc >= 0.0) {
      const double q = -0.5 * (qb + std::copysign(std::sqrt(disc), qb));
      consider(q / qa);
      if (q != 0.0) consider(qc / q);
    }
  }
  return lowest;
}

// A lower bound of g on [0, 1] from its values a0, a1 and slopes b0, b1 (per unit u) at the ends
// and c = max|g⁗| / 4!: g(u) >= H(u) − c u²(1 − u)² (the cubic Hermite remainder), with
// u²(1 − u)² bounded by u² on [0, 1/3], 1/16 on [1/3, 2/3] and (1 − u)² on [2/3, 1]. The bound
// keeps the ends exact, so a surface leaving zero with a positive slope is cleared at once.
double EnvelopeMinimum(double a0, double b0, double a1, double b1, double c) {
  // H(u) = a0 + b0 u + h2 u² + h3 u³.
  const double h2 = -3.0 * a0 - 2.0 * b0 + 3.0 * a1 - b1;
  const double h3 = 2.0 * a0 + b0 - 2.0 * a1 + b1;
  return std::min({CubicMinimum(a0, b0, h2 - c, h3, 0.0, 1.0 / 3.0),
                   CubicMinimum(a0 - c / 16.0, b0, h2, h3, 1.0 / 3.0, 2.0 / 3.0),
                   CubicMinimum(a0 - c, b0 + 2.0 * c, h2 - c, h3, 2.0 / 3.0, 1.0)});
}

// A cruder bound for the common case, without root finding: the Hermite basis weights of a0, a1
// are convex, those of b0, b1 lie within ±4/27.
inline double QuickMinimum(double a0, double b0, double a1, double b1, double c) {
  const double lower = a0 < a1 ? a0 : a1;
  const double falling = -b0 > 0.0 ? -b0 : 0.0, rising = b1 > 0.0 ? b1 : 0.0;
  return lower - (4.0 / 27.0) * (falling + rising) - 0.0625 * c;
}

// Everything the solver needs of one phase set, in scaled coordinates. Vectors are padded to a
// multiple of 4 (numerics::PaddedMatrix) with zeros.
struct PhaseData {
  PaddedMatrix m_padded;  // m = D⁻¹ M D, for v = m y
  PaddedMatrix m_active;  // m on the moving components (see active_)
  double norm_inf = 0.0;  // ‖m‖∞
  std::vector<Model::WatchedSurface> watched;
  PaddedMatrix rows;     // watched surfaces over y, signed: R = side · G D (>= 0 on the side the
                         // phases describe), for the surfaces' slopes R v
  PaddedMatrix observe;  // [R; T D]: watched surfaces, then scene link torques
  // Per watched surface: kCrossingTolerance ‖R_w‖₁ (a crossing's least depth at typical state
  // magnitudes, times the state's size in the step), and bounds of its derivatives.
  std::vector<double> tolerance;
  std::vector<double> bound2;        // |R_w| |m| 1: |g''| <= bound2 · ‖v‖∞
  std::vector<double> bound3;        // |R_w| |m|³ 1: |g⁗| <= bound3 · ‖v‖∞
  std::vector<std::uint64_t> reach;  // per surface, `words` words: the components whose motion
                                     // can reach it (built on first need)
  // The full step over h in increment form, built after kStepsBeforeCaching full steps.
  long full_steps = 0;
  bool has_step = false;
  PaddedMatrix step;    // [Φ; 0; S; 0] over the active part of v (zero rows pad to 4)
  double growth = 1.0;  // e^{‖m‖∞ h}: bounds ‖v‖ over a step by growth · ‖v(t)‖
  double defect = 0.0;  // roundoff of one cached step, relative to the state scale
};

// Taylor series of one step in pieces: on piece p (start z_p, v_p, length dt),
// v(s) = Σ_k u_{p,k} s^k and z(s) = z_p + dt Σ_k u_{p,k} s^{k+1}/(k+1), s ∈ [0, 1].
// Vectors are stored with the padded stride of the state.
struct Series {
  int stride = 0;
  int pieces = 0;
  double dt = 0.0;
  std::vector<int> first;       // per piece: index of u_{p,0}
  std::vector<int> terms;       // per piece
  std::vector<double> u;        // the u vectors
  std::vector<double> z_start;  // per piece
  const double* U(int p, int k) const {
    return u.data() + static_cast<size_t>(first[p] + k) * stride;
  }
};

// A polynomial in s on [0, 1], coefficients c_0 … c_K.
struct Polynomial {
  std::vector<double> c;
  double fourth = 0.0;  // bound of |p⁗| on [0, 1]

  void Eval(double s, double* p, double* dp) const {
    double value = 0.0, slope = 0.0;
    for (int k = static_cast<int>(c.size()) - 1; k >= 0; --k) {
      slope = slope * s + value;
      value = value * s + c[k];
    }
    *p = value;
    *dp = slope;
  }
  void BoundFourth() {
    fourth = 0.0;
    for (size_t k = 4; k < c.size(); ++k) {
      fourth += std::abs(c[k]) * static_cast<double>(k * (k - 1) * (k - 2) * (k - 3));
    }
  }
};

// Whether g falls throughout [0, 1] (so it has one root there), from the same data as
// EnvelopeMinimum: the cubic Hermite interpolant's slope is off g's by at most
// (√3/216) max|g⁗| = (√3/9) c, so a slope below minus that everywhere keeps g' < 0.
bool Falling(double a0, double b0, double a1, double b1, double c) {
  // H'(u) = b0 + 2 h2 u + 3 h3 u², a quadratic: its maximum on [0, 1].
  const double h2 = -3.0 * a0 - 2.0 * b0 + 3.0 * a1 - b1;
  const double h3 = 2.0 * a0 + b0 - 2.0 * a1 + b1;
  double highest = std::max(b0, b1);
  if (h3 < 0.0) {  // concave slope: the vertex may be a maximum inside
    const double u = -h2 / (3.0 * h3);
    if (u > 0.0 && u < 1.0) highest = std::max(highest, b0 + u * (2.0 * h2 + 3.0 * h3 * u));
  }
  return highest + (std::sqrt(3.0) / 9.0) * c < 0.0;
}

// Where the polynomial first goes below −tol on [0, limit]: the bracket [*lo, *hi] with
// p >= −tol proven on [0, *lo] and p(*hi) < −tol, located to `resolution`. False when p stays
// above −tol (to the bound) on [0, limit].
bool FirstBelow(const Polynomial& poly, double tol, double limit, double resolution, double* lo,
                double* hi) {
  struct Interval {
    double a, pa, da, b, pb, db;
    int depth;
  };
  Interval stack[kMaxSearchDepth + 2];
  int top = 0;
  double p0, d0, p1, d1;
  poly.Eval(0.0, &p0, &d0);
  poly.Eval(limit, &p1, &d1);
  stack[top++] = {0.0, p0, d0, limit, p1, d1, 0};
  while (top > 0) {
    const Interval iv = stack[--top];
    if (iv.pa < -tol) {
      *lo = *hi = iv.a;
      return true;
    }
    const double width = iv.b - iv.a;
    const double c = poly.fourth * width * width * width * width * (1.0 / 24.0);
    if (EnvelopeMinimum(iv.pa, iv.da * width, iv.pb, iv.db * width, c) >= -tol) continue;
    const bool finest = width <= resolution || iv.depth >= kMaxSearchDepth;
    if (iv.pb < -tol &&
        (c / 16.0 <= tol || finest || Falling(iv.pa, iv.da * width, iv.pb, iv.db * width, c))) {
      *lo = iv.a;
      *hi = iv.b;
      return true;
    }
    if (finest) continue;  // a graze at roundoff
    const double mid = iv.a + 0.5 * width;
    double pm, dm;
    poly.Eval(mid, &pm, &dm);
    stack[top++] = {mid, pm, dm, iv.b, iv.pb, iv.db, iv.depth + 1};
    stack[top++] = {iv.a, iv.pa, iv.da, mid, pm, dm, iv.depth + 1};
  }
  return false;
}

// The root of the polynomial in [lo, hi] (p(lo) >= 0 > p(hi), or p(lo) < 0: then lo), located to
// `resolution`; returns the end on the far side (p < 0), so the state there is past the surface.
double RootPastSurface(const Polynomial& poly, double lo, double hi, double resolution) {
  double p, dp;
  poly.Eval(lo, &p, &dp);
  if (p < 0.0) return lo;
  double s = dp < 0.0 ? lo - p / dp : 0.5 * (lo + hi);
  if (!(s > lo && s < hi)) s = 0.5 * (lo + hi);
  for (int iteration = 0; iteration < kMaxRootIterations && hi - lo > resolution; ++iteration) {
    poly.Eval(s, &p, &dp);
    if (p >= 0.0) {
      lo = s;
    } else {
      hi = s;
    }
    if (hi - lo <= resolution) break;
    double next = dp != 0.0 ? s - p / dp : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    // Newton at the root to roundoff: nudge across it so that the bracket closes.
    if (std::abs(next - s) < 0.5 * resolution) {
      next = std::clamp(s + (p >= 0.0 ? 0.5 : -0.5) * resolution, lo, hi);
    }
    s = next;
  }
  return hi;
}

// For each surface row (over the first rows.cols() components), the components j from which M's
// graph (j feeds i when M_ij != 0) leads to a component the row reads: the only ones whose motion
// can move the surface. `words` 64-bit words per row into *reach; *inputs is work space.
void Reach(const Eigen::MatrixXd& m, const Eigen::MatrixXd& rows, int words,
           std::vector<std::uint64_t>* inputs_storage, std::vector<int>* stack_storage,
           std::vector<std::uint64_t>* reach_storage) {
  const int n = static_cast<int>(m.rows());
  inputs_storage->assign(static_cast<size_t>(n) * words, 0);  // row i: the components feeding i
  std::uint64_t* inputs = inputs_storage->data();
  for (int j = 0; j < n; ++j) {  // branch-free: the zero pattern is irregular
    const double* column = m.col(j).data();
    const std::uint64_t bit = std::uint64_t{1} << (j % 64);
    for (int i = 0; i < n; ++i) {
      inputs[static_cast<size_t>(i) * words + j / 64] |= (column[i] != 0.0) ? bit : 0;
    }
  }
  reach_storage->assign(static_cast<size_t>(rows.rows()) * words, 0);
  stack_storage->resize(n);
  int* stack = stack_storage->data();
  for (int w = 0; w < rows.rows(); ++w) {
    std::uint64_t* r = reach_storage->data() + static_cast<size_t>(w) * words;
    int top = 0;
    for (int i = 0; i < rows.cols(); ++i) {
      if (rows(w, i) != 0.0) {
        r[i / 64] |= std::uint64_t{1} << (i % 64);
        stack[top++] = i;
      }
    }
    while (top > 0) {
      const int i = stack[--top];
      for (int word = 0; word < words; ++word) {
        std::uint64_t fresh = inputs[static_cast<size_t>(i) * words + word] & ~r[word];
        r[word] |= fresh;
        while (fresh != 0) {
          stack[top++] = 64 * word + __builtin_ctzll(fresh);
          fresh &= fresh - 1;
        }
      }
    }
  }
}

bool Disjoint(const std::uint64_t* a, const std::uint64_t* b, int words) {
  for (int i = 0; i < words; ++i) {
    if ((a[i] & b[i]) != 0) return false;
  }
  return true;
}

class ExactIntegrator {
 public:
  ExactIntegrator(const Model& model, const SimulationOptions& options)
      : model_(model),
        options_(options),
        n_(model.augmented_size()),
        stride_(PaddedMatrix::Padded(model.augmented_size())),
        active_(model.augmented_size() - model.forcing_size()),
        active_stride_(PaddedMatrix::Padded(active_)),
        words_((model.augmented_size() + 63) / 64) {}

  SimulationResult Run();

 private:
  PhaseData* Data(const Phases& phases);
  void BuildStep(PhaseData* data);
  // Sums the step's Taylor series from (z, v) over tau into series_; sets z1, v1 to its end.
  void ExpandStep(const PhaseData& data, const double* z, const double* v, double tau, double* z1,
                  double* v1);
  // z(s), v(s) on piece p of series_.
  void EvaluateSeries(int p, double s, double* z, double* v) const;
  // The earliest crossing of a candidate surface on series_: piece, s and watched index.
  bool FindEvent(const PhaseData& data, const std::vector<int>& candidates,
                 const std::vector<double>& tolerance, double resolution_s, int* piece, double* s,
                 int* crossed);
  void Record(OutputRecorder* recorder, int k, const double* y, const double* torque);

  const Model& model_;
  const SimulationOptions& options_;
  const int n_;       // augmented size
  const int stride_;  // n_ padded to a multiple of 4
  // z = [x; w; w']: the input slopes w' are constant within a phase set, so v = z' is zero in
  // them and m's rows for them are zero. Steps and series work on the first active_ components.
  const int active_;
  const int active_stride_;
  std::unordered_map<Phases, PhaseData> cache_;
  double h_ = 0.0;
  Eigen::VectorXd scale_, inverse_scale_;
  SimulationResult result_;
  Series series_;
  std::vector<double> work_;
  std::vector<Polynomial> polynomials_;
  std::vector<Model::KnownSide> known_;  // the side of the surface crossed at an event
  // Work space of Data().
  const int words_;  // 64-bit words of a component mask
  Eigen::MatrixXd m_scratch_, observe_scratch_;
  PaddedMatrix transposed_scratch_;
  std::vector<double> vector_scratch_;
  std::vector<std::uint64_t> inputs_scratch_;
  std::vector<int> stack_scratch_;
  // Work space of BuildStep().
  Eigen::MatrixXd build_m_, build_s_, build_phi_, build_step_, build_product_;
  // Output map of kept samples: speed of each scene mass, twist of each flexible scene link.
  std::vector<int> speed_index_;
  std::vector<int> twist_index_;  // −1 for rigid links
};

MILLKIT_HOT PhaseData* ExactIntegrator::Data(const Phases& phases) {
  auto it = cache_.find(phases);
  if (it != cache_.end()) return &it->second;
  // Scratch matrices are members: a run meets a few dozen phase sets, each built once.
  PhaseData data;
  const Eigen::MatrixXd system = model_.SystemMatrix(phases);
  Eigen::MatrixXd& m = m_scratch_;
  m.resize(n_, n_);
  for (int j = 0; j < n_; ++j) {
    for (int i = 0; i < n_; ++i) m(i, j) = system(i, j) * scale_[j] * inverse_scale_[i];
  }
  data.m_padded.Assign(m);
  data.m_active.Assign(m.topLeftCorner(active_, active_));
  data.norm_inf = 0.0;
  for (int i = 0; i < n_; ++i) {
    double row = 0.0;
    for (int j = 0; j < n_; ++j) row += std::abs(m(i, j));
    data.norm_inf = std::max(data.norm_inf, row);
  }
  data.growth = std::exp(std::min(data.norm_inf * h_, 700.0));
  data.watched = model_.Watched(phases);
  const int count = static_cast<int>(data.watched.size());
  const Eigen::MatrixXd torque = model_.LinkTorqueRows(phases, system);
  // Surfaces and torques do not read the input slopes (Model::surfaces, LinkTorqueRows).
  Eigen::MatrixXd& observe = observe_scratch_;
  observe.resize(count + torque.rows(), active_);
  for (int j = 0; j < active_; ++j) {
    for (int i = 0; i < count; ++i) {
      observe(i, j) =
          data.watched[i].side * model_.surfaces()(data.watched[i].index, j) * scale_[j];
    }
    for (int l = 0; l < torque.rows(); ++l) observe(count + l, j) = torque(l, j) * scale_[j];
  }
  data.rows.Assign(observe.topRows(count));
  data.observe.Assign(observe);
  // |g''| = |R_w m v| and |g⁗| = |R_w m³ v| with v zero in the slopes, whose rows of m are zero:
  // only the active block counts. ‖R_w m_aaᵏ‖₁ <= |R_w| (|m_aa|ᵏ 1), one vector for all surfaces.
  data.tolerance.resize(count);
  data.bound2.resize(count);
  data.bound3.resize(count);
  {
    Eigen::MatrixXd& abs_m = build_product_;
    abs_m = m.topLeftCorner(active_, active_).cwiseAbs();
    transposed_scratch_.Assign(abs_m);
    std::vector<double>& work = vector_scratch_;
    work.assign(3 * active_stride_, 0.0);
    double *ones = work.data(), *r1 = ones + active_stride_, *r2 = r1 + active_stride_;
    for (int i = 0; i < active_; ++i) ones[i] = 1.0;
    transposed_scratch_.Apply(ones, r1);  // |m| 1
    transposed_scratch_.Apply(r1, r2);    // |m|² 1
    transposed_scratch_.Apply(r2, ones);  // |m|³ 1, into the first vector
    for (int w = 0; w < count; ++w) {
      double size = 0.0, bound2 = 0.0, bound3 = 0.0;
      for (int i = 0; i < active_; ++i) {
        const double r = std::abs(observe(w, i));
        size += r;
        bound2 += r * r1[i];
        bound3 += r * ones[i];
      }
      data.tolerance[w] = kCrossingTolerance * size;
      data.bound2[w] = bound2;
      data.bound3[w] = bound3;
    }
  }
  return &cache_.emplace(phases, std::move(data)).first->second;
}

void ExactIntegrator::BuildStep(PhaseData* data) {
  // m is block upper triangular over [active; slopes] with zero slope rows, so the active blocks
  // of S and Φ are those of the active block of m.
  const int a = active_, as = active_stride_;
  Eigen::MatrixXd &m = build_m_, &s = build_s_, &phi = build_phi_;
  data->m_active.CopyTo(&m);
  numerics::ExpAndPhi1(m, h_, &s, &phi);
  Eigen::MatrixXd& step = build_step_;
  step.setZero(2 * as, a);
  step.topRows(a) = phi;
  step.middleRows(as, a) = s;
  data->step.Assign(step);
  data->has_step = true;
  ++result_.summary.phase_sets;
  if (!options_.estimate_error) return;
  // The same step along another rounding path (one more halving and doubling): the difference
  // estimates a step's roundoff, z's through Φ v (‖v‖ <= ‖m‖∞ ‖z‖), v's through S and one more
  // step of Φ ≈ h.
  Eigen::MatrixXd s2, phi2;
  numerics::ExpAndPhi1(m, h_, &s2, &phi2, 1);
  data->defect = data->norm_inf * ((phi - phi2).cwiseAbs().rowwise().sum().maxCoeff() +
                                   (s - s2).cwiseAbs().rowwise().sum().maxCoeff() * h_);
}

MILLKIT_HOT void ExactIntegrator::ExpandStep(const PhaseData& data, const double* z,
                                             const double* v, double tau, double* z1, double* v1) {
  Series& series = series_;
  series.stride = stride_;
  series.pieces = std::max(1, static_cast<int>(std::ceil(data.norm_inf * tau)));
  series.dt = tau / series.pieces;
  series.first.resize(series.pieces);
  series.terms.resize(series.pieces);
  series.z_start.resize(static_cast<size_t>(series.pieces) * stride_);
  Copy(z, stride_, z1);
  Copy(v, stride_, v1);
  int used = 0;  // vectors stored in series.u
  auto vector = [&](int index) {
    const size_t need = static_cast<size_t>(index + 1) * stride_;
    if (series.u.size() < need) series.u.resize(2 * need);
    return series.u.data() + static_cast<size_t>(index) * stride_;
  };
  for (int p = 0; p < series.pieces; ++p) {
    Copy(z1, stride_, series.z_start.data() + static_cast<size_t>(p) * stride_);
    series.first[p] = used;
    Copy(v1, stride_, vector(used));
    int terms = 1;
    // Terms until they no longer change v at the piece's start scale (‖v‖ grows by at most e
    // over a piece, and a cancelling sum is no more accurate than that).
    const double start = numerics::MaxAbsPadded(v1, stride_);
    if (start != 0.0) {
      for (int k = 1; k < kMaxTaylorTerms; ++k) {
        double* u = vector(used + k);
        data.m_active.Apply(u - stride_, u);
        const double factor = series.dt / k;
        double size = 0.0;
        for (int i = 0; i < active_stride_; ++i) {
          u[i] *= factor;
          v1[i] += u[i];
          const double magnitude = std::abs(u[i]);
          size = magnitude > size ? magnitude : size;
        }
        terms = k + 1;
        if (size <= 0x1p-53 * start) break;
      }
    }
    series.terms[p] = terms;
    // z at the piece's end: z_p + dt Σ u_k / (k + 1).
    const double* u = series.u.data() + static_cast<size_t>(used) * stride_;
    for (int k = 0; k < terms; ++k, u += stride_) {
      const double factor = series.dt / (k + 1);
      for (int i = 0; i < active_stride_; ++i) z1[i] += factor * u[i];
    }
    used += terms;
  }
}

void ExactIntegrator::EvaluateSeries(int p, double s, double* z, double* v) const {
  const Series& series = series_;
  const int terms = series.terms[p];
  const double* z0 = series.z_start.data() + static_cast<size_t>(p) * stride_;
  // Horner over the terms, each a whole vector: v = Σ u_k s^k, z = z0 + dt s Σ u_k s^k/(k+1).
  std::fill(v, v + stride_, 0.0);
  std::fill(z, z + stride_, 0.0);
  for (int k = terms - 1; k >= 0; --k) {
    const double* u = series.U(p, k);
    const double inverse = 1.0 / (k + 1);
    for (int i = 0; i < active_stride_; ++i) {
      v[i] = v[i] * s + u[i];
      z[i] = z[i] * s + u[i] * inverse;
    }
  }
  const double factor = series.dt * s;
  for (int i = 0; i < stride_; ++i) z[i] = z0[i] + factor * z[i];
}

MILLKIT_HOT bool ExactIntegrator::FindEvent(const PhaseData& data,
                                            const std::vector<int>& candidates,
                                            const std::vector<double>& tolerance,
                                            double resolution_s, int* piece, double* s_event,
                                            int* crossed) {
  const Series& series = series_;
  work_.resize(std::max<size_t>(work_.size(), data.rows.ld()));
  polynomials_.resize(data.watched.size());
  for (int p = 0; p < series.pieces; ++p) {
    const int terms = series.terms[p];
    for (int w : candidates) polynomials_[w].c.assign(terms + 1, 0.0);
    // c_0 = R z_p, c_{k+1} = dt·R u_k / (k + 1) (R signed).
    data.rows.Apply(series.z_start.data() + static_cast<size_t>(p) * stride_, work_.data());
    for (int w : candidates) polynomials_[w].c[0] = work_[w];
    for (int k = 0; k < terms; ++k) {
      data.rows.Apply(series.U(p, k), work_.data());
      const double factor = series.dt / (k + 1);
      for (int w : candidates) polynomials_[w].c[k + 1] = factor * work_[w];
    }
    double best = std::numeric_limits<double>::infinity();
    for (int w : candidates) {
      Polynomial& poly = polynomials_[w];
      poly.BoundFourth();
      double lo = 0.0, hi = 0.0;
      if (!FirstBelow(poly, tolerance[w], std::min(best, 1.0), resolution_s, &lo, &hi)) continue;
      const double root = RootPastSurface(poly, lo, hi, resolution_s);
      if (root < best) {
        best = root;
        *crossed = w;
      }
    }
    if (best <= 1.0) {
      *piece = p;
      *s_event = best;
      return true;
    }
  }
  return false;
}

MILLKIT_HOT void ExactIntegrator::Record(OutputRecorder* recorder, int k, const double* y,
                                         const double* torque) {
  const int links = static_cast<int>(twist_index_.size());
  if (recorder->keep_samples()) {
    double* speed = recorder->speed(k);
    for (size_t i = 0; i < speed_index_.size(); ++i) {
      speed[i] = scale_[speed_index_[i]] * y[speed_index_[i]];
    }
    double* twist = recorder->twist(k);
    for (int l = 0; l < links; ++l) {
      twist[l] = twist_index_[l] >= 0 ? scale_[twist_index_[l]] * y[twist_index_[l]]
                                      : torque[l] /
                                            model_.reduced_scene().links[l].stiffness_Nm_per_rad;
    }
  }
  recorder->Commit(k, torque);
}

MILLKIT_HOT SimulationResult ExactIntegrator::Run() {
  const auto started = std::chrono::steady_clock::now();
  const Scene& scene = model_.reduced_scene();  // outputs convert back in the recorder
  SimulationSummary& summary = result_.summary;
  summary.solver = "exact";
  summary.reduction = model_.reduction().report;
  OutputRecorder recorder(model_, options_, OutputTimes(scene, options_), &result_);
  const std::vector<double>& times = recorder.times();
  const int samples = recorder.size();
  h_ = CachedStepLength(scene, options_, times);
  scale_ = AugmentedScale(model_);
  inverse_scale_ = scale_.cwiseInverse();
  const int links = static_cast<int>(scene.links.size());
  for (size_t i = 0; i < scene.masses.size(); ++i) {
    speed_index_.push_back(model_.SpeedIndex(model_.reduction().group_of_mass[i]));
  }
  for (int l = 0; l < links; ++l) {
    const int f = model_.FlexibleIndexOf(l);
    twist_index_.push_back(f >= 0 ? model_.TwistIndex(f) : -1);
  }

  Eigen::VectorXd z0 = model_.InitialState();
  if (options_.initial_state) {
    z0.head(model_.state_size()) = options_.initial_state->head(model_.state_size());
  }
  Phases phases = options_.initial_state ? model_.InitialPhases(z0) : model_.InitialPhases();
  PhaseData* data = Data(phases);
  const std::vector<double> breakpoints = scene.InputBreakpoints();
  size_t next_breakpoint = 0;

  // Scaled state y and its derivative v (padded with zeros), the same at the end of a step, and
  // the watched surfaces' values at the step's start (g0) and end (`end` holds [g; link
  // torques]); their slopes (dg0, dg1) only when a step needs them.
  const int surfaces = model_.surface_count();
  const int max_ld = PaddedMatrix::Padded(2 * stride_ + surfaces + links);
  std::vector<double> y(stride_, 0.0), v(stride_, 0.0), y1(stride_, 0.0), v1(stride_, 0.0);
  std::vector<double> g0(max_ld), dg0(max_ld), end(max_ld), dg1(max_ld), out(max_ld);
  for (int i = 0; i < n_; ++i) y[i] = z0[i] / scale_[i];
  Eigen::VectorXd unscaled(n_), unscaled_v(n_), unscaled_a(n_);
  std::vector<std::uint64_t> moving(words_);
  double v_norm = 0.0;
  auto refresh = [&] {  // v, g0 and ‖v‖ from y in the current phases
    data->m_padded.Apply(y.data(), v.data());
    data->rows.Apply(y.data(), g0.data());
    v_norm = numerics::MaxAbsPadded(v.data(), stride_);
  };
  refresh();

  double t = 0.0;
  bool on_grid = true;  // t is exactly the previous output time
  long stalled = 0;
  std::vector<int> candidates;
  std::vector<double> tolerance, slack(surfaces);
  int k = 0;
  if (times.front() == 0.0) {
    data->observe.Apply(y.data(), end.data());
    Record(&recorder, 0, y.data(), end.data() + data->watched.size());
    k = 1;
  } else {
    on_grid = false;
  }

  while (k < samples) {
    const double t_grid = times[k];
    double target = t_grid;
    bool at_breakpoint = false;
    if (next_breakpoint < breakpoints.size() &&
        breakpoints[next_breakpoint] <= t_grid * (1.0 + 4 * kEps)) {
      target = std::min(breakpoints[next_breakpoint], t_grid);
      at_breakpoint = true;
    }
    const bool at_grid = target >= t_grid * (1.0 - 4 * kEps);
    if (at_grid) target = t_grid;
    const double tau = target - t;
    // The cached step serves a step between output times whose gap is h to roundoff of the times
    // themselves (the state lands a few ulps of t off: as exact as t can be stated).
    const bool full_step =
        on_grid && at_grid && std::abs(tau - h_) <= 8 * kEps * std::max(std::abs(t_grid), h_);
    if (full_step && !data->has_step && ++data->full_steps >= kStepsBeforeCaching) {
      BuildStep(data);
    }
    const int count = static_cast<int>(data->watched.size());
    bool expanded = false;
    double growth = data->growth;
    if (full_step && data->has_step) {
      data->step.Apply(v.data(), out.data());
      for (int i = 0; i < active_stride_; ++i) {
        y1[i] = y[i] + out[i];
        v1[i] = out[active_stride_ + i];
      }
      for (int i = active_stride_; i < stride_; ++i) y1[i] = y[i];  // (v1 stays zero there)
      summary.error_estimate += data->defect;
    } else {
      ExpandStep(*data, y.data(), v.data(), tau, y1.data(), v1.data());
      expanded = true;
      growth = std::exp(std::min(data->norm_inf * tau, 700.0));
    }
    ++summary.steps;
    // Non-finite states show in v first (y1 = y + Φ v).
    const double v1_norm = numerics::MaxAbsPadded(v1.data(), active_stride_);  // zero beyond
    if (!std::isfinite(v1_norm)) {
      summary.message = "state became non-finite at t = " + std::to_string(t);
      break;
    }
    data->observe.Apply(y1.data(), end.data());

    // Which watched surfaces can cross within the step: the bounds first, exact work after. The
    // surfaces are signed (>= 0 on the watched side). The first pass is branch-free over all of
    // them with the smallest tolerance (state size 1): the chord between the ends is off g by at
    // most max|g''| τ²/8. The surfaces it does not clear get their slopes and the tighter tiers.
    const double l_factor = growth * v_norm * tau * tau * 0.125;
    const double c_factor = growth * v_norm * tau * tau * tau * tau * (1.0 / 24.0);
    double least = 0.0;
    {
      const double* __restrict a0 = g0.data();
      const double* __restrict a1 = end.data();
      const double* __restrict bound2 = data->bound2.data();
      const double* __restrict tol = data->tolerance.data();
      double* __restrict out_slack = slack.data();
      for (int w = 0; w < count; ++w) {
        const double lower = a0[w] < a1[w] ? a0[w] : a1[w];
        out_slack[w] = lower - bound2[w] * l_factor + tol[w];
        least = out_slack[w] < least ? out_slack[w] : least;
      }
    }
    const bool any = least < 0.0;
    candidates.clear();
    if (any) {
      data->rows.Apply(v.data(), dg0.data());
      data->rows.Apply(v1.data(), dg1.data());
      const double size = std::max({1.0, numerics::MaxAbsPadded(y.data(), stride_),
                                    numerics::MaxAbsPadded(y1.data(), stride_)});
      bool moving_known = false;
      tolerance.resize(count);
      for (int w = 0; w < count; ++w) {
        tolerance[w] = data->tolerance[w] * size;
        if (slack[w] >= 0.0) continue;
        if (end[w] < -tolerance[w]) {
          candidates.push_back(w);
          continue;
        }
        const double a0 = g0[w], a1 = end[w], b0 = dg0[w] * tau, b1 = dg1[w] * tau;
        const double c = data->bound3[w] * c_factor;
        if (QuickMinimum(a0, b0, a1, b1, c) >= -tolerance[w]) continue;
        if (!moving_known) {
          std::fill(moving.begin(), moving.end(), 0);
          for (int i = 0; i < n_; ++i) {
            if (v[i] != 0.0) moving[i / 64] |= std::uint64_t{1} << (i % 64);
          }
          moving_known = true;
        }
        // g is constant, and a1 >= −tolerance.
        if (data->reach.empty()) {
          Eigen::MatrixXd& m = m_scratch_;
          data->m_padded.CopyTo(&m);
          data->rows.CopyTo(&observe_scratch_);
          Reach(m, observe_scratch_, words_, &inputs_scratch_, &stack_scratch_, &data->reach);
        }
        if (Disjoint(moving.data(), data->reach.data() + static_cast<size_t>(w) * words_, words_)) {
          continue;
        }
        if (EnvelopeMinimum(a0, b0, a1, b1, c) < -tolerance[w]) candidates.push_back(w);
      }
    }

    if (!candidates.empty()) {
      if (!expanded) ExpandStep(*data, y.data(), v.data(), tau, y1.data(), v1.data());
      const double resolution_s = kStallUlps * kEps * std::max(std::abs(t) + tau, h_) / series_.dt;
      int piece = 0, crossed = -1;
      double s = 0.0;
      if (FindEvent(*data, candidates, tolerance, resolution_s, &piece, &s, &crossed)) {
        const double tau_event = (piece + s) * series_.dt;
        EvaluateSeries(piece, s, y1.data(), v1.data());
        // Sides of the other surfaces from the motion before the event (Model::Classify).
        std::fill(out.begin(), out.end(), 0.0);
        data->m_active.Apply(v1.data(), out.data());
        for (int i = 0; i < n_; ++i) {
          unscaled[i] = scale_[i] * y1[i];
          unscaled_v[i] = scale_[i] * v1[i];
          unscaled_a[i] = scale_[i] * out[i];
        }
        const Model::WatchedSurface surface = data->watched[crossed];
        known_.assign(1, {surface.index, -surface.side});
        const Phases next = model_.Classify(unscaled, unscaled_v, unscaled_a, known_);
        if (tau_event <= kStallUlps * kEps * std::max(std::abs(t), h_)) {
          if (++stalled > kMaxStalledEvents) {
            summary.message = "events do not advance time at t = " + std::to_string(t) +
                              " (chattering between " + model_.DescribePhases(phases) + " and " +
                              model_.DescribePhases(next) + ")";
            break;
          }
        } else {
          stalled = 0;
        }
        t += tau_event;
        summary.event_times_s.push_back(t);
        y.swap(y1);
        phases = next;
        data = Data(phases);
        refresh();
        on_grid = false;
        if (++summary.events > options_.max_events) {
          summary.message = "more than max_events = " + std::to_string(options_.max_events) +
                            " switching events by t = " + std::to_string(t);
          break;
        }
        continue;
      }
      if (!expanded) {  // the series' end replaced the cached step's: observe that one
        data->observe.Apply(y1.data(), end.data());
      }
    }

    y.swap(y1);
    v.swap(v1);
    Copy(end.data(), count, g0.data());
    v_norm = v1_norm;
    t = target;
    if (at_breakpoint) {
      // Inputs from their right limit at the breakpoint itself: a breakpoint snapped onto a
      // sample time a few ulps away must not be read as still inside the ramp before it.
      for (int i = 0; i < n_; ++i) unscaled[i] = scale_[i] * y[i];
      model_.SetForcing(breakpoints[next_breakpoint], &unscaled);
      for (int i = 0; i < n_; ++i) y[i] = unscaled[i] / scale_[i];
      refresh();
      data->observe.Apply(y.data(), end.data());
      ++next_breakpoint;
    }
    if (at_grid) {
      on_grid = true;
      Record(&recorder, k, y.data(), end.data() + count);
      ++k;
    } else {
      on_grid = false;
    }
  }
  summary.success = summary.message.empty();
  summary.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return std::move(result_);
}

}  // namespace

SimulationResult SimulateExact(const Model& model, const SimulationOptions& options) {
  options.Validate(model.scene());
  ExactIntegrator integrator(model, options);
  return integrator.Run();
}

}  // namespace millkit::driveline
