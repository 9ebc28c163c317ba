// Event-exact piecewise-linear integrator (issue 2). See simulation.h for the contract.
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
//    over pieces dt with ‖M dt‖∞ <= 1; z follows by integrating it term by term. A recorder
//    low-pass state y' = a (T z − y), read by no other state and no surface, is left out of the
//    series and of ‖M‖: it takes the other components' polynomial through its decay exactly
//    (numerics/exponential_moments.h), so that a filter faster than the line does not cut every
//    such step into more pieces.
// Events: a watched surface g = r·z changes side within a step. Each step first bounds every
// watched surface from its values at the two ends: the chord is off g by at most max|g''| τ²/8,
// |g''| = |r M v| <= |r| |M| 1 · G ‖v(t)‖∞, G = e^{‖M‖∞ τ}, or for ‖M‖∞ h above 2 the sharper
// sup_{s <= h} ‖exp(M s)‖∞ (SupExpNorm: near 1 for a damped motion, where e^{‖M‖∞ h} is 10^5).
// Those it does not clear are bounded from their values and slopes: with u = s/τ, the cubic
// Hermite interpolant differs from g by at most max|g⁗| τ⁴ u²(1 − u)²/4!,
// |g⁗| <= |r| |M|³ 1 · G ‖v(t)‖∞; then by the chord again from the acceleration itself,
// |g''| <= ‖r‖₁ G ‖M v(t)‖∞, small once a damped fast mode has decayed. A surface that the motion
// cannot reach (no path in M's graph from a moving component to the surface's) stays put.
// Only a surface whose bound reaches below zero is looked at exactly: on the step's Taylor series
// it is a polynomial in s, searched left to right with the same bound on halved intervals, and its
// first root is located by safeguarded Newton to a few ulps of time.
// Everything runs in scaled coordinates y = D⁻¹ z, D = diag(typical magnitudes): D⁻¹ M D has a
// norm near the fastest mode's frequency, where the raw M mixes units (N·m/rad over kg·m² next
// to 1) and would need many more Taylor terms. An input slope is scaled by at most value / h, and
// D is rebalanced (BalanceScale) where a loop couples states of very different scales.
// Stiff phase sets (issue 11: a near-step load, a fast drive loop, a heavily damped coupling),
// where a step's Taylor series would need more than kMaxTaylorPieces pieces, are stepped on a
// ladder of propagators over h / 2^j built in long double (StiffAdvance): substeps halve until
// the chord bound with the acceleration m v clears every surface, and double again once the fast
// transient has decayed; the short substeps that still do not clear get the Taylor search. A
// surface's bound reads the acceleration through its own row (|R_w| E_j |m v|, E_j bounding
// exp(m s) entry by entry), so a fast mode the surface reads only through slow couplings does not
// hold it near zero at the finest level (a tiny gap beside a stiff oscillation). Where that
// bound fails too, the fast decaying modes of m (real eigenvalues λ h <= −kFastModeRate: a heavy
// damper between two masses) are taken apart and each bounded by its size, since it only decays;
// the rest is expanded in powers of σ m (FastModesClear). A surface reading the difference of two
// speeds that accelerate together is then bounded by that difference, not by their common
// acceleration, and the fast mode's roundoff (which every derivative multiplies by its rate)
// only by its size. The
// cost is O(log ‖m‖ h) per step and per transient, the cache of phase data is bounded in bytes,
// and a surface that never clears ends the run with a reason (kMaxStiffSubsteps), never a hang.
// The substeps' sum is compensated (a drift below the state's ulp is kept), and a surface held
// within its tolerance past zero, moving across, for kMaxSubstepsOnSurface substeps is crossed
// there, with what that may cost in the error estimate.
// The run itself (output times, breakpoints, classification at events, the escape from a
// degenerate switch, the summary) is the hybrid driver's (hybrid_driver.h); this file is its
// per-phase-set integrator.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include "driveline/hybrid_driver.h"
#include "driveline/output_recorder.h"
#include "millkit/driveline/simulation.h"
#include "millkit/io/number_format.h"
#include "numerics/exp_phi.h"
#include "numerics/exponential_moments.h"
#include "numerics/median_interval.h"
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
// Roots are located to this many ulps of t (the hybrid driver's "events that do not advance time"
// use the same figure).
constexpr double kStallUlps = 64.0;
constexpr int kMaxRootIterations = 100;
constexpr int kMaxTaylorTerms = 60;
// Building [Φ; S] costs about as much as 10 Taylor steps; phase sets that last a few samples
// (contact transients, brief separations) never pay it.
constexpr long kStepsBeforeCaching = 8;
// Halvings of one polynomial before a surface that keeps within its bound is called a graze.
constexpr int kMaxSearchDepth = 60;
// A step whose Taylor series would need more pieces than this (‖m‖∞ τ, a stiff phase set: a fast
// drive loop, a heavily damped coupling) is taken in substeps on a ladder of exact propagators
// over h / 2^j instead (StiffAdvance): its cost grows with log(‖m‖∞ h), not with ‖m‖∞ h.
// 16, from bench_stiff: at 64 a coupling damped at 1e4 (‖m‖ h ≈ 20) took 0.65 ms, every step
// expanded because the Taylor bound's growth e^{‖m‖ h} cleared no surface; at 16, 0.07 ms; the
// bundled bite (‖m‖ h < 1) is unchanged.
constexpr double kMaxTaylorPieces = 16.0;
// Stiff substeps short enough for the exact event search on their Taylor series.
constexpr double kSearchPieces = 4.0;
// The ladder's finest level, where sup ‖exp(m s)‖∞ <= e^{‖m‖∞ σ} is used as it is.
constexpr double kGrowthBaseNorm = 0.125;
// Above this ‖m‖∞ h (and up to kMaxTaylorPieces) a phase set's growth over a step, which bounds
// the surfaces' motion, is sup ‖exp(m s)‖∞ from the propagators over h / 2^j (SupExpNorm) instead
// of e^{‖m‖∞ h}: a damped motion's propagator stays near 1 where e^{‖m‖∞ h} reaches 10^5, every
// surface then failed the bound, and every step was expanded and searched (fast-lowpass random
// line 10163: 3 ms a run against 0.2 ms).
constexpr double kTightGrowthNorm = 2.0;
// Cached phase data beyond this many bytes is dropped and rebuilt on need: a run that visits very
// many phase sets keeps a bounded memory.
constexpr size_t kMaxCacheBytes = size_t{64} << 20;
// Ulps of rounding per entry of a ladder propagator (built in long double, rounded once).
constexpr double kLadderUlps = 4.0;
// A real eigenvalue of m with λ h <= −kFastModeRate is a fast mode: where the stiff substeps'
// entry-by-entry bounds fail, it is taken apart and bounded by its size (it decays), not by its
// curvature (FastModesClear).
constexpr double kFastModeRate = 64.0;
// Orders of the slow rest's expansion in that bound (each reads one more product with m).
constexpr int kFastOrders = 3;
// Stiff substeps in a row that may end with one watched surface past zero but within its crossing
// tolerance, moving across and not cleared by the bounds, before that is taken as its crossing
// (StiffAdvance: a surface held there by the rounding of a heavily damped motion).
constexpr int kMaxSubstepsOnSurface = 64;
// Substeps of one stiff step before the run gives up (a clear failure instead of a hang).
constexpr long kMaxStiffSubsteps = 200'000;
// And in the whole run (about 2.5 s on one core): a run that crawls ends with its reason.
constexpr long kMaxStiffSubstepsPerRun = 20'000'000;
// Typical magnitude of each component of z: states from the model, forcing from the sources.
// An input slope is scaled by at most value / h: a ramp shorter than the step h (a load written as
// a near-step) then lasts one short step with a large scaled slope, instead of putting
// value / rise into m's norm (and into the cost of every step) for the whole run.
Eigen::VectorXd AugmentedScale(const Model& model, double h) {
  const int nx = model.state_size(), nw = model.forcing_size();
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(model.augmented_size());
  scale.head(nx) = model.StateScale();
  // A recorder low-pass state y' = a (T z − y) at kFilterScaleMargin times its torque's scale: its
  // row of the scaled matrix, a (T D / d_y, −1), then has the norm a (1 + 1/margin), and a leg's
  // Taylor pieces (norm × length) pay for the filter's own rate only, not for the size of the
  // torque's terms against y's.
  constexpr double kFilterScaleMargin = 1024.0;
  for (int l = 0; l < static_cast<int>(model.reduced_scene().links.size()); ++l) {
    if (model.FilterIndexOf(l) >= 0) scale[model.FilterIndexOf(l)] *= kFilterScaleMargin;
  }
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
    scale[nx + nw + 1 + s] = std::max(std::min(slope, value / h), 1.0);
  }
  return scale;
}

// Rebalances the state part of `scale` (Osborne's iteration in powers of 2) on |M| of the phase
// sets that carry the most coupling (Model::CouplingPhaseSets). The model's scales follow each
// link's and the drive's own magnitudes; where a loop couples them at very different scales (a
// drive with kp/lag far above limit/J) the scaled matrix's norm, and with it the cost of a step and
// the looseness of every bound, is far above the fastest rate of the motion. The balanced scales
// are taken only when they cut the norm by more than kBalanceGain, so well-scaled scenes keep their
// scales, and their roundoff, exactly.
constexpr double kBalanceGain = 8.0;
void BalanceScale(const Model& model, Eigen::VectorXd* scale) {
  const int n = model.augmented_size(), nx = model.state_size();
  Eigen::MatrixXd magnitude = Eigen::MatrixXd::Zero(n, n);
  for (const Phases& phases : model.CouplingPhaseSets()) {
    magnitude = magnitude.cwiseMax(model.SystemMatrix(phases).cwiseAbs());
  }
  auto scaled_norm = [&](const Eigen::VectorXd& d) {
    double norm = 0.0;
    for (int i = 0; i < n; ++i) {
      double row = 0.0;
      for (int j = 0; j < n; ++j) row += magnitude(i, j) * d[j] / d[i];
      norm = std::max(norm, row);
    }
    return norm;
  };
  Eigen::VectorXd balanced = *scale;
  for (int sweep = 0; sweep < 100; ++sweep) {
    bool changed = false;
    for (int i = 0; i < nx; ++i) {
      double row = 0.0, column = 0.0;
      for (int j = 0; j < n; ++j) {
        if (j == i) continue;
        row += magnitude(i, j) * balanced[j] / balanced[i];
        column += magnitude(j, i) * balanced[i] / balanced[j];
      }
      if (row == 0.0 || column == 0.0) continue;
      // Scaling component i by f divides its row by f and multiplies its column by f.
      const double f = std::exp2(std::round(0.5 * std::log2(row / column)));
      if (f != 1.0 && (row / f + column * f) < 0.95 * (row + column)) {
        balanced[i] *= f;
        changed = true;
      }
    }
    if (!changed) break;
  }
  if (scaled_norm(balanced) * kBalanceGain < scaled_norm(*scale)) *scale = balanced;
}

// The step whose propagator is cached per phase set: the scene's sample interval, or for given
// output times the median gap (an oscillogram's sampling interval).
double CachedStepLength(const Scene& scene, const SimulationOptions& options) {
  const double sample_step = 1.0 / scene.sample_rate_Hz;
  return options.output_times ? numerics::MedianInterval(*options.output_times, sample_step)
                              : sample_step;
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

// An upper bound of sup_{0 <= s <= h} ‖exp(m s)‖∞. Over s <= σ_p = h / 2^p, ‖m‖∞ σ_p <= 1:
// e^{‖m‖∞ σ_q} at σ_q = σ_p / 2^(q-p), ‖m‖∞ σ_q <= kGrowthBaseNorm, times max(1, ‖exp(m σ_j)‖∞)
// for j = q … p + 1 (any s <= σ_{j-1} is σ_j plus a shorter time); then over [k σ_p, (k + 1) σ_p]
// that times ‖exp(m σ_p)^k‖∞, the largest over k < 2^p. The propagators come from exp(m σ_q)'s
// series by squaring and products, each norm raised by their rounding. A damped motion's bound
// stays near 1 where e^{‖m‖∞ h} is 10^5.
double SupExpNorm(const Eigen::MatrixXd& m, double norm_inf, double h) {
  const double theta = norm_inf * h;
  const int p = std::max(0, static_cast<int>(std::ceil(std::log2(theta))));
  const int q = std::max(p, static_cast<int>(std::ceil(std::log2(theta / kGrowthBaseNorm))));
  const double theta_q = std::ldexp(theta, -q);
  const Eigen::Index n = m.rows();
  const Eigen::MatrixXd a = std::ldexp(h, -q) * m;
  Eigen::MatrixXd s = Eigen::MatrixXd::Identity(n, n), term = s, next(n, n);
  double rest = theta_q;  // bound of the next term's ‖·‖∞
  for (int k = 1; k <= kMaxTaylorTerms && rest > 0x1p-60; ++k) {
    numerics::Multiply(term, a, &next);
    term = next / k;
    s += term;
    rest *= theta_q / (k + 1);
  }
  // Each product's rounding, relative, and the series' rest (carried through the squarings).
  const double rounding = 1.0 + 8.0 * static_cast<double>(n) * kEps;
  auto norm = [&](const Eigen::MatrixXd& x) {
    return x.cwiseAbs().rowwise().sum().maxCoeff() * rounding + 2.0 * rest;
  };
  double inner = std::exp(theta_q);
  for (int j = q; j > p; --j) {
    inner *= std::max(1.0, norm(s));
    numerics::Multiply(s, s, &next);
    s = next;
  }
  double outer = 1.0;
  Eigen::MatrixXd power = s;
  for (long k = 1; k < (long{1} << p); ++k) {
    outer = std::max(outer, norm(power));
    numerics::Multiply(power, s, &next);
    power = next;
  }
  return inner * outer;
}

// Everything the solver needs of one phase set, in scaled coordinates. Vectors are padded to a
// multiple of 4 (numerics::PaddedMatrix) with zeros.
struct PhaseData {
  PaddedMatrix m_padded;  // m = D⁻¹ M D, for v = m y
  PaddedMatrix m_active;  // m on the moving components (see active_)
  double norm_inf = 0.0;  // ‖m‖∞
  // The recorder low-pass states apart (their columns of m and of the surfaces zero off the
  // diagonal): m_active with their rows zeroed, each one's rate a = −m(y, y) and row off the
  // diagonal (padded), and ‖m‖∞ over the other rows, which sizes the Taylor pieces, tells a stiff
  // phase set and bounds the surfaces' motion (the other rows move on their own, and the surfaces
  // read only them). Else series_norm = ‖m‖∞.
  bool lowpass_apart = false;
  PaddedMatrix m_series;
  std::vector<double> lowpass_rate;
  std::vector<double> lowpass_rows;  // per low-pass state, stride_ entries
  double series_norm = 0.0;
  std::vector<Model::WatchedSurface> watched;
  PaddedMatrix rows;      // watched surfaces over y, signed: R = side · G D (>= 0 on the side the
                          // phases describe), for the surfaces' slopes R v
  PaddedMatrix abs_rows;  // |R|: |R| |y| is the size of the terms a surface sums (its roundoff)
  PaddedMatrix observe;   // [R; T D]: watched surfaces, then scene link torques
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
  PaddedMatrix step;  // [Φ; 0; S; 0] over the active part of v (zero rows pad to 4)
  double growth = 1.0;  // e^{series_norm h}: bounds ‖v‖ over a step by growth · ‖v(t)‖ (BoundNorm)
  double defect = 0.0;  // roundoff of one cached step, relative to the state scale
  // Stiff phase sets (StiffAdvance), built on first need: per level j = 0 … ladder.size() − 1,
  // the step [Φ; 0; S; 0] over σ_j = h / 2^j, sup_{s <= σ_j} ‖exp(m s)‖∞ and the roundoff of Φ
  // and S (‖ΔΦ‖∞ + ‖ΔS‖∞ σ_j, from a ladder along another rounding path).
  std::vector<PaddedMatrix> ladder;
  std::vector<double> ladder_growth;
  std::vector<double> ladder_defect;
  // Per level j and watched surface w (index (j · surfaces + w) · active_stride_): the row
  // |R_w| E_j over the active components, E_j >= sup_{s <= σ_j} |exp(m s)| entry by entry. Then
  // |g_w''| <= (|R_w| E_j) |m v| over a substep: far below ‖R_w‖₁ sup ‖exp(m s)‖∞ ‖m v‖∞ where
  // the fast motion is in components that a surface reads only through slow couplings.
  std::vector<double> ladder_reach;
  // The fast modes (kFastModeRate), built on first need by FastModesClear: simple real
  // eigenvalues λ_i, their right eigenvectors v_i (‖v_i‖∞ = 1) and left ones w_i (w_i · v_i = 1)
  // over the active components, each active_stride_ long; and per level j, surface w and mode i
  // (index (j · surfaces + w) · fast_count + i) a bound of |R_w exp(m s) v_i| for s <= σ_j:
  // |R_w v_i| + σ_j (|R_w| E_j) |m v_i − λ_i v_i| (the eigenvector's residual, moved by exp).
  bool fast_built = false;
  int fast_count = 0;
  std::vector<double> fast_right, fast_left, fast_reach;
  int level = 0;                 // the substep level last taken
  std::vector<double> row_norm;  // ‖R_w‖₁ per watched surface
  size_t bytes = 0;              // approximate memory held
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
  // Per piece and recorder low-pass state taken apart: the coefficients c_0 … c_K+1 of its
  // input over the piece in s (ExactIntegrator::LowpassAt).
  int lowpass = 0;
  const PhaseData* data = nullptr;  // the phase set the series was summed in
  std::vector<double> lowpass_input;
  double* LowpassInput(int p, int r) {
    return lowpass_input.data() + (static_cast<size_t>(p) * lowpass + r) * (kMaxTaylorTerms + 1);
  }
  const double* LowpassInput(int p, int r) const {
    return lowpass_input.data() + (static_cast<size_t>(p) * lowpass + r) * (kMaxTaylorTerms + 1);
  }
  const double* U(int p, int k) const {
    return u.data() + static_cast<size_t>(first[p] + k) * stride;
  }
};

inline double Dot(const double* a, const double* b, int n) {
  double sum = 0.0;
  for (int i = 0; i < n; ++i) sum += a[i] * b[i];
  return sum;
}

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

class ExactIntegrator final : public ModeIntegrator {
 public:
  ExactIntegrator(const Model& model, const SimulationOptions& options)
      : model_(model),
        options_(options),
        n_(model.augmented_size()),
        stride_(PaddedMatrix::Padded(model.augmented_size())),
        active_(model.augmented_size() - model.forcing_size()),
        active_stride_(PaddedMatrix::Padded(active_)),
        words_((model.augmented_size() + 63) / 64) {
    for (int l = 0; l < static_cast<int>(model.reduced_scene().links.size()); ++l) {
      if (model.FilterIndexOf(l) >= 0) lowpass_.push_back(model.FilterIndexOf(l));
    }
    lowpass_weights_.resize(kMaxTaylorTerms + 2);
    core_mask_.assign(stride_, 1.0);
    for (const int y : lowpass_) core_mask_[y] = 0.0;
  }

  double time_scale() const override { return h_; }
  std::string Start(const Eigen::VectorXd& z0, const Phases& phases,
                    SimulationSummary* summary) override;
  void Advance(double t, const Leg& leg, LegEnd* end) override { AdvanceLeg(t, leg, end); }
  void EventMotion(Eigen::VectorXd* z, std::vector<Eigen::VectorXd>* derivatives) override;
  void Switch(const Phases& phases, double t) override;
  void ApplyBreakpoint(double breakpoint, double t) override;
  void Record(OutputRecorder* recorder, int k, double /*t_output*/) override {
    Record(recorder, k, y_.data(), end_.data() + data_->watched.size());
  }
  void Finish(SimulationSummary* /*summary*/) override {}
  void State(Eigen::VectorXd* z) const override {
    z->resize(n_);
    for (int i = 0; i < n_; ++i) (*z)[i] = scale_[i] * y_[i];
  }

 private:
  // Advance itself (a virtual function cannot be cloned per target; see MILLKIT_HOT).
  void AdvanceLeg(double t, const Leg& leg, LegEnd* end);
  // v, g0 and ‖v‖ from y in the current phases.
  void Refresh();
  // Whether model surface `index` is not watched (escaping a degenerate switch).
  bool Ignored(int index) const { return ignored_ != nullptr && (*ignored_)[index] != 0; }
  PhaseData* Data(const Phases& phases);
  void BuildStep(PhaseData* data);
  // Sums the step's Taylor series from (z, v) over tau into series_; sets z1, v1 to its end.
  void ExpandStep(const PhaseData& data, const double* z, const double* v, double tau, double* z1,
                  double* v1);
  // z(s), v(s) on piece p of series_.
  void EvaluateSeries(int p, double s, double* z, double* v) const;
  // The recorder low-pass states taken apart, z and v at s on piece p of series_ (the other
  // components of z already there).
  void LowpassAt(const PhaseData& data, int p, double s, double* z, double* v) const;
  // The earliest crossing of a candidate surface on series_: piece, s and watched index.
  bool FindEvent(const PhaseData& data, const std::vector<int>& candidates,
                 const std::vector<double>& tolerance, double resolution_s, int* piece, double* s,
                 int* crossed);
  void Record(OutputRecorder* recorder, int k, const double* y, const double* torque);
  // exp(m h) and Φ(h) over the active states of a phase set whose low-pass states are apart,
  // those taken exactly through their decay (with `extra_doublings`: another rounding path).
  void SplitStep(const PhaseData& data, int extra_doublings, Eigen::MatrixXd* s,
                 Eigen::MatrixXd* phi);
  // Builds the propagator ladder of a stiff phase set.
  void BuildLadder(PhaseData* data);
  // Advances (y, v) over τ in a stiff phase set by substeps on the ladder: each substep is
  // accepted when every watched surface keeps clear of zero by the chord bound
  // |g''| <= ‖R_w‖₁ sup‖exp(m s)‖∞ ‖m v‖∞ (v at the substep's start), else halved; one short enough
  // (‖m‖∞ σ <= kSearchPieces) that still does not clear gets the exact search on its Taylor
  // series. True at an event: *tau_event from the start, *crossed, y1 and v1 at the event (past
  // the surface). False: y1 and v1 at τ, end = [R; T] y1.
  bool StiffAdvance(PhaseData* data, double t, double tau, const double* y, const double* v,
                    const double* g0, double* y1, double* v1, double* end, double* tau_event,
                    int* crossed);
  // ‖v‖∞ over the components the series and the surfaces' bounds follow: with the low-pass
  // states apart, the others only; NaN when one is not finite.
  double BoundNorm(const PhaseData& data, const double* v) const {
    if (!data.lowpass_apart) return numerics::MaxAbsPadded(v, active_stride_);
    double norm = 0.0;
    for (int i = 0; i < active_stride_; ++i) {
      const double size = std::abs(v[i]) * core_mask_[i];
      norm = size > norm || std::isnan(size) ? size : norm;
    }
    return norm;
  }
  // Finds a stiff phase set's fast modes (PhaseData::fast_*); none where m has no simple, well
  // separated real eigenvalue below −kFastModeRate / h with a well-conditioned eigenvector.
  void BuildFastModes(PhaseData* data);
  // Whether watched surface w keeps clear of zero over a stiff substep at `level` (length σ) by
  // the chord bound with the fast modes apart: |g''(s)| = |R_w exp(m s) a|, a = m v at the
  // substep's start, split as Σ c_i v_i + r, each mode bounded by its size, the rest by
  // sup|R_w exp(m s) r| <= |R_w r| + σ sup|R_w exp(m s) m r| to order kFastOrders (m r split
  // again), the last order by |R_w| E_j |r|. `margin` is min(g(0), g(σ)) plus the tolerance.
  // The chain of split vectors does not depend on w: it is built once a substep (*chain_built).
  bool FastModesClear(PhaseData* data, int level, double sigma, int w, double margin,
                      bool* chain_built);
  // Whether surface w cannot move: no component that reaches it moves (v = 0 there).
  bool StaticSurface(PhaseData* data, int w, const double* v);
  // Per watched surface: the crossing tolerance at states y and y1, kCrossingTolerance times
  // the size of the terms the surface sums, max(‖R_w‖₁, |R_w| max(|y|, |y1|)). A surface is
  // measured against its own terms: a large state it does not read (a drive integrator far
  // from its limit-scaled size) must not widen the tolerance of a 1e-10 rad gap.
  void Tolerances(const PhaseData& data, const double* y, const double* y1,
                  std::vector<double>* tolerance) {
    const int count = static_cast<int>(data.watched.size());
    // Sized, not cleared (this runs on every step and substep): entries from active_ on stay
    // zero, and Apply writes every entry of the terms it reads.
    size_scratch_.resize(stride_, 0.0);
    for (int i = 0; i < active_; ++i) size_scratch_[i] = std::max(std::abs(y[i]), std::abs(y1[i]));
    if (terms_scratch_.size() < static_cast<size_t>(data.abs_rows.ld())) {
      terms_scratch_.resize(data.abs_rows.ld());
    }
    data.abs_rows.Apply(size_scratch_.data(), terms_scratch_.data());
    tolerance->resize(count);
    for (int w = 0; w < count; ++w) {
      (*tolerance)[w] = std::max(data.tolerance[w], kCrossingTolerance * terms_scratch_[w]);
    }
  }

  const Model& model_;
  const SimulationOptions& options_;
  const int n_;       // augmented size
  const int stride_;  // n_ padded to a multiple of 4
  // z = [x; w; w']: the input slopes w' are constant within a phase set, so v = z' is zero in
  // them and m's rows for them are zero. Steps and series work on the first active_ components.
  const int active_;
  const int active_stride_;
  std::unordered_map<Phases, PhaseData> cache_;
  // While escaping a degenerate switch: per model surface, 1 for one not watched; else null.
  const std::vector<char>* ignored_ = nullptr;
  Phases phases_;              // the current phases
  PhaseData* data_ = nullptr;  // their data
  SimulationSummary* summary_ = nullptr;
  long stiff_substeps_ = 0;
  // The watched surface the last accepted stiff substeps ended on to roundoff while moving
  // across, and how many in a row (reset at a switch).
  int on_surface_ = -1;
  int on_surface_substeps_ = 0;
  // A crossing so taken: the time its surface needs to cross its tolerance band (at most what is
  // left of the run), and the derivative before the switch (zero time: none pending).
  double held_crossing_time_ = 0.0;
  double run_end_ = 0.0;  // the last output time
  std::vector<double> held_crossing_v_;
  size_t cache_bytes_ = 0;
  double h_ = 0.0;
  Eigen::VectorXd scale_, inverse_scale_;
  Series series_;
  std::vector<double> work_;
  std::vector<Polynomial> polynomials_;
  // The state: scaled y and v = y' (padded with zeros), the same at the end of a step (or at an
  // event), the watched surfaces at the step's start (g0_) and end (end_ holds [g; link
  // torques]), their slopes (dg0_, dg1_) when a step needs them, and ‖v‖∞.
  std::vector<double> y_, v_, y1_, v1_, g0_, dg0_, end_, dg1_, out_;
  double v_norm_ = 0.0;
  std::vector<int> lowpass_;  // the recorder low-pass states
  // LowpassAt's weights g_0 … g_terms at z = weights_z_, and e^z.
  mutable std::vector<double> lowpass_weights_;
  mutable double weights_z_ = 1.0, weights_decay_ = 0.0;
  mutable int weights_terms_ = -1;
  std::vector<double> core_mask_;  // 0 at the low-pass states, else 1 (BoundNorm)
  Eigen::VectorXd unscaled_;
  std::vector<std::uint64_t> moving_scratch_;
  std::vector<int> candidates_;
  std::vector<double> tolerance_, slack_;
  // Work space of Data().
  const int words_;  // 64-bit words of a component mask
  Eigen::MatrixXd m_scratch_, observe_scratch_;
  PaddedMatrix transposed_scratch_;
  std::vector<double> vector_scratch_;
  std::vector<std::uint64_t> inputs_scratch_;
  std::vector<int> stack_scratch_;
  // Work space of BuildStep() and StiffAdvance().
  Eigen::MatrixXd build_m_, build_s_, build_phi_, build_step_, build_product_;
  // Work space of SplitStep().
  Eigen::MatrixXd split_c_, split_u_, split_next_, split_s_rows_, split_phi_rows_, split_product_;
  std::vector<double> split_weights_;
  std::vector<double> stiff_y_, stiff_v_, stiff_g_, stiff_a_, stiff_out_;
  std::vector<double> accel_;  // m v at a Taylor or cached step's start (AdvanceLeg)
  std::vector<int> stiff_candidates_;
  std::vector<double> size_scratch_, terms_scratch_;
  std::vector<double> stiff_tolerance_;
  std::vector<double> stiff_carry_, stiff_carry1_;
  std::vector<char> stiff_bounded_out_;
  // FastModesClear's chain, per order k: the rest r_k, the modes' coefficients and R r_k.
  std::vector<double> fast_rest_, fast_coefficients_, fast_rows_, fast_next_;
  std::vector<std::uint64_t> moving_;
  // Output map of kept samples: speed of each scene mass, twist of each flexible scene link.
  std::vector<int> speed_index_;
  std::vector<int> twist_index_;  // −1 for rigid links
};

MILLKIT_HOT PhaseData* ExactIntegrator::Data(const Phases& phases) {
  auto it = cache_.find(phases);
  if (it != cache_.end()) return &it->second;
  // Only the caller's current phase set is held by pointer, and it is being replaced.
  if (cache_bytes_ > kMaxCacheBytes) {
    cache_.clear();
    cache_bytes_ = 0;
  }
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
  data.lowpass_apart = !lowpass_.empty();
  for (const int y : lowpass_) {
    for (int i = 0; i < n_; ++i)
      data.lowpass_apart = data.lowpass_apart && (i == y || m(i, y) == 0.0);
    data.lowpass_apart = data.lowpass_apart && (model_.surfaces().col(y).array() == 0.0).all();
  }
  data.series_norm = data.norm_inf;
  Eigen::MatrixXd core;  // the series' matrix when the low-pass rows are apart
  if (data.lowpass_apart) {
    core = m.topLeftCorner(active_, active_);
    data.lowpass_rows.assign(lowpass_.size() * stride_, 0.0);
    for (size_t r = 0; r < lowpass_.size(); ++r) {
      const int y = lowpass_[r];
      data.lowpass_rate.push_back(-m(y, y));
      for (int j = 0; j < n_; ++j) {
        if (j != y) data.lowpass_rows[r * stride_ + j] = m(y, j);
      }
      core.row(y).setZero();
    }
    data.m_series.Assign(core);
    data.series_norm = core.cwiseAbs().rowwise().sum().maxCoeff();
    // The rows beyond the active block (the input slopes') are zero.
  }
  data.growth = std::exp(std::min(data.series_norm * h_, 700.0));
  if (data.series_norm * h_ > kTightGrowthNorm && data.series_norm * h_ <= kMaxTaylorPieces) {
    // The series' matrix: the active block itself unless the low-pass rows are apart.
    data.growth = std::min(
        data.growth,
        SupExpNorm(data.lowpass_apart ? core : Eigen::MatrixXd(m.topLeftCorner(active_, active_)),
                   data.series_norm, h_));
  }
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
  data.abs_rows.Assign(observe.topRows(count).cwiseAbs());
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
    work.assign(size_t{3} * active_stride_, 0.0);
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
  data.row_norm.resize(count);
  for (int w = 0; w < count; ++w) data.row_norm[w] = observe.row(w).cwiseAbs().sum();
  data.bytes =
      sizeof(double) *
          (static_cast<size_t>(n_) * n_ * 2 + static_cast<size_t>(count + torque.rows()) * n_ * 2 +
           (data.lowpass_apart ? static_cast<size_t>(n_) * n_ : 0) + data.lowpass_rows.size()) +
      sizeof(PhaseData);
  cache_bytes_ += data.bytes;
  return &cache_.emplace(phases, std::move(data)).first->second;
}

void ExactIntegrator::BuildStep(PhaseData* data) {
  // m is block upper triangular over [active; slopes] with zero slope rows, so the active blocks
  // of S and Φ are those of the active block of m.
  const int a = active_, as = active_stride_;
  Eigen::MatrixXd &m = build_m_, &s = build_s_, &phi = build_phi_;
  data->m_active.CopyTo(&m);
  // A phase set stiff only through a fast recorder low-pass (‖m‖∞ h > kMaxTaylorPieces, the rest
  // not; StiffAdvance takes the others): the low-pass rows apart (SplitStep). Through
  // ExpAndPhi1's doublings of the whole m, the runs' roundoff on random lines filtered at 1–10
  // times the sampling rate went above what central differences tell (sensitivity_test.cpp, a
  // fast recorder low-pass).
  const bool split = data->lowpass_apart && data->norm_inf * h_ > kMaxTaylorPieces;
  if (split) {
    SplitStep(*data, 0, &s, &phi);
  } else {
    numerics::ExpAndPhi1(m, h_, &s, &phi);
  }
  Eigen::MatrixXd& step = build_step_;
  step.setZero(Eigen::Index{2} * as, a);
  step.topRows(a) = phi;
  step.middleRows(as, a) = s;
  data->step.Assign(step);
  data->has_step = true;
  ++summary_->phase_sets;
  if (!options_.estimate_error) return;
  // The same step along another rounding path (one more halving and doubling): the difference
  // estimates a step's roundoff, z's through Φ v (‖v‖ <= ‖m‖∞ ‖z‖), v's through S and one more
  // step of Φ ≈ h.
  Eigen::MatrixXd s2, phi2;
  if (split) {
    SplitStep(*data, 1, &s2, &phi2);
  } else {
    numerics::ExpAndPhi1(m, h_, &s2, &phi2, 1);
  }
  data->defect = data->norm_inf * ((phi - phi2).cwiseAbs().rowwise().sum().maxCoeff() +
                                   (s - s2).cwiseAbs().rowwise().sum().maxCoeff() * h_);
}

void ExactIntegrator::SplitStep(const PhaseData& data, int extra_doublings, Eigen::MatrixXd* s,
                                Eigen::MatrixXd* phi) {
  // m = [C 0; R −A] over (other, low-pass) states: exp(m σ) = [E 0; L e^{−Aσ}] with E = exp(C σ)
  // (ExpAndPhi1 of C alone) and, row r, L_r = σ Σ_k g_k(−a_r σ) u_k, u_k = R_r (C σ)^k / k! (the
  // decay of the input R_r E(u) over the substep, numerics/exponential_moments.h); Φ's row
  // ∫₀^σ L_r = σ² Σ_k g_{k+1}(−a_r σ) / (k+1) u_k and σ g_0 on the diagonal. σ = h / 2^q with
  // ‖C‖∞ σ <= 1 (‖u C‖₁ <= ‖u‖₁ ‖C‖∞), then q doublings Φ ← Φ (I + S), S ← S².
  const int a = active_;
  Eigen::MatrixXd& c = split_c_;
  data.m_series.CopyTo(&c);
  const double theta = data.series_norm * h_;
  const int doublings =
      (theta > 1.0 ? static_cast<int>(std::ceil(std::log2(theta))) : 0) + extra_doublings;
  const double sigma = std::ldexp(h_, -doublings);
  const double theta_b = std::ldexp(theta, -doublings);
  numerics::ExpAndPhi1(c, sigma, s, phi);
  // Terms 0 … K of the rows: the tail after K is below θ^{K+1}/(K+1)! e^θ.
  int last = 0;
  for (double tail = theta_b; last < kMaxTaylorTerms - 2 && tail * std::exp(theta_b) > 0x1p-54;) {
    ++last;
    tail *= theta_b / (last + 1);
  }
  const auto lowpass = static_cast<Eigen::Index>(lowpass_.size());
  Eigen::MatrixXd &u = split_u_, &next = split_next_;
  u.setZero(lowpass, a);
  for (Eigen::Index r = 0; r < lowpass; ++r) {
    for (int j = 0; j < a; ++j) u(r, j) = data.lowpass_rows[r * stride_ + j];
  }
  std::vector<double>& g = split_weights_;
  g.resize(static_cast<size_t>(lowpass) * (last + 2));
  for (Eigen::Index r = 0; r < lowpass; ++r) {
    numerics::ExponentialMoments(-data.lowpass_rate[r] * sigma, last + 1, &g[r * (last + 2)]);
  }
  Eigen::MatrixXd &s_rows = split_s_rows_, &phi_rows = split_phi_rows_;
  s_rows.setZero(lowpass, a);
  phi_rows.setZero(lowpass, a);
  for (int k = 0; k <= last; ++k) {
    if (k > 0) {
      next.noalias() = u * c;
      u = (sigma / k) * next;
    }
    for (Eigen::Index r = 0; r < lowpass; ++r) {
      const double* w = &g[r * (last + 2)];
      s_rows.row(r) += (sigma * w[k]) * u.row(r);
      phi_rows.row(r) += (sigma * sigma * w[k + 1] / (k + 1)) * u.row(r);
    }
  }
  for (Eigen::Index r = 0; r < lowpass; ++r) {
    const int y = lowpass_[r];
    s->row(y) = s_rows.row(r);
    phi->row(y) = phi_rows.row(r);
    (*s)(y, y) = std::exp(-data.lowpass_rate[r] * sigma);
    (*phi)(y, y) = sigma * g[r * (last + 2)];
  }
  Eigen::MatrixXd& product = split_product_;
  for (int i = 0; i < doublings; ++i) {
    numerics::Multiply(*phi, *s, &product);
    *phi += product;
    numerics::Multiply(*s, *s, &product);
    *s = product;
  }
}

void ExactIntegrator::BuildLadder(PhaseData* data) {
  const int a = active_, as = active_stride_;
  Eigen::MatrixXd& m = build_m_;
  data->m_active.CopyTo(&m);
  // Levels down to the one the Taylor search takes (‖m‖∞ σ <= kSearchPieces), and further down to
  // ‖m‖∞ σ <= kGrowthBaseNorm for the growth bound only.
  const double theta = data->norm_inf * h_;
  const int search = std::max(0, static_cast<int>(std::ceil(std::log2(theta / kSearchPieces))));
  const int base =
      std::max(search, static_cast<int>(std::ceil(std::log2(theta / kGrowthBaseNorm))));
  std::vector<Eigen::MatrixXd> s, phi;
  numerics::ExpAndPhi1Ladder(m, h_, base, &s, &phi);
  // sup_{s <= σ_j} ‖exp(m s)‖∞ <= max(1, ‖S_{j+1}‖∞) · sup_{s <= σ_{j+1}} (any s in (σ_{j+1}, σ_j]
  // is σ_{j+1} plus a shorter time).
  std::vector<double> growth(base + 1);
  growth[base] = std::exp(std::ldexp(theta, -base));
  for (int j = base - 1; j >= 0; --j) {
    growth[j] = std::max(1.0, s[j + 1].cwiseAbs().rowwise().sum().maxCoeff()) * growth[j + 1];
  }
  // The same entry by entry: E_base = exp(|m| σ_base), its series of non-negative terms summed
  // until the rest (every entry of (|m| σ)^k is at most θ_base^k) is below 1e-20, which is added
  // to every entry; E_j = max(E_{j+1}, |S_{j+1}| E_{j+1}) with S's rounding added to every entry.
  const int count = static_cast<int>(data->watched.size());
  data->ladder_reach.assign(static_cast<size_t>(search + 1) * count * as, 0.0);
  {
    const double theta_base = std::ldexp(theta, -base);
    Eigen::MatrixXd abs_m = std::ldexp(h_, -base) * m.cwiseAbs();
    Eigen::MatrixXd bound = Eigen::MatrixXd::Identity(a, a), term = bound, next;
    double rest = theta_base;  // θ^k / k! for the next term
    for (int k = 1; k <= kMaxTaylorTerms && rest * std::exp(theta_base) > 1e-20; ++k) {
      next.noalias() = term * abs_m;
      term = next / k;
      bound += term;
      rest *= theta_base / (k + 1);
    }
    bound.array() += rest * std::exp(theta_base);
    Eigen::MatrixXd abs_rows, reach;
    data->abs_rows.CopyTo(&abs_rows);
    for (int j = base;; --j) {
      if (j <= search) {
        reach.noalias() = abs_rows.leftCols(a) * bound;
        for (int w = 0; w < count; ++w) {
          for (int i = 0; i < a; ++i) {
            data->ladder_reach[(static_cast<size_t>(j) * count + w) * as + i] = reach(w, i);
          }
        }
      }
      if (j == 0) break;
      Eigen::MatrixXd abs_s = s[j].cwiseAbs();
      abs_s.array() += kLadderUlps * kEps * abs_s.rowwise().sum().maxCoeff();
      next.noalias() = abs_s * bound;
      bound = bound.cwiseMax(next);
    }
  }
  data->ladder.resize(search + 1);
  data->ladder_growth.assign(growth.begin(), growth.begin() + search + 1);
  data->ladder_defect.assign(search + 1, 0.0);
  Eigen::MatrixXd& step = build_step_;
  for (int j = 0; j <= search; ++j) {
    step.setZero(Eigen::Index{2} * as, a);
    step.topRows(a) = phi[j];
    step.middleRows(as, a) = s[j];
    data->ladder[j].Assign(step);
  }
  if (options_.estimate_error) {
    // Built in long double, the ladder's own error is that of rounding to double: a few ulps of
    // each entry, carried into y through Φ and into v through S (one more step of Φ ≈ σ).
    for (int j = 0; j <= search; ++j) {
      data->ladder_defect[j] = kLadderUlps * kEps *
                               (phi[j].cwiseAbs().rowwise().sum().maxCoeff() +
                                s[j].cwiseAbs().rowwise().sum().maxCoeff() * std::ldexp(h_, -j));
    }
  }
  // Start where a fresh transient needs it: the Taylor level.
  data->level = search;
  const size_t bytes =
      sizeof(double) * (static_cast<size_t>(search + 1) * 2 * as * a + data->ladder_reach.size());
  data->bytes += bytes;
  cache_bytes_ += bytes;
  ++summary_->phase_sets;
}

void ExactIntegrator::BuildFastModes(PhaseData* data) {
  data->fast_built = true;
  const int a = active_, as = active_stride_;
  Eigen::MatrixXd& m = build_m_;
  data->m_active.CopyTo(&m);
  if (!m.allFinite()) return;
  const Eigen::EigenSolver<Eigen::MatrixXd> right(m);
  const Eigen::EigenSolver<Eigen::MatrixXd> left(m.transpose());
  if (right.info() != Eigen::Success || left.info() != Eigen::Success) return;
  const Eigen::VectorXcd& values = right.eigenvalues();
  const Eigen::VectorXcd& left_values = left.eigenvalues();
  std::vector<double> lambdas;
  for (int i = 0; i < a; ++i) {
    const double lambda = values[i].real();
    if (values[i].imag() != 0.0 || !(lambda * h_ <= -kFastModeRate)) continue;
    // Simple and well separated (|λ_i − λ_k| >= 1e-3 |λ_i|), so that its eigenvectors are
    // well determined; the left one is m^T's eigenvector of the nearest eigenvalue.
    bool separated = true;
    int match = -1;
    double nearest = std::numeric_limits<double>::infinity();
    for (int k = 0; k < a && separated; ++k) {
      if (k != i && std::abs(values[k] - values[i]) < 1e-3 * std::abs(lambda)) separated = false;
      const double distance = std::abs(left_values[k] - values[i]);
      if (distance < nearest) {
        nearest = distance;
        match = k;
      }
    }
    if (!separated || match < 0 || left_values[match].imag() != 0.0 ||
        !(nearest <= 1e-6 * std::abs(lambda))) {
      continue;
    }
    Eigen::VectorXd v = right.eigenvectors().col(i).real();
    Eigen::VectorXd u = left.eigenvectors().col(match).real();
    const double size = v.cwiseAbs().maxCoeff();
    if (!(size > 0.0)) continue;
    v /= size;
    const double product = u.dot(v);
    // The mode's condition number ‖u‖₁ ‖v‖∞ / |u · v|: an ill-conditioned split could move
    // slow motion into the fast part and back; such a mode stays with the rest.
    if (!(std::abs(product) * 1e8 >= u.cwiseAbs().sum())) continue;
    u /= product;
    data->fast_right.resize(static_cast<size_t>(data->fast_count + 1) * as, 0.0);
    data->fast_left.resize(static_cast<size_t>(data->fast_count + 1) * as, 0.0);
    for (int k = 0; k < a; ++k) {
      data->fast_right[static_cast<size_t>(data->fast_count) * as + k] = v[k];
      data->fast_left[static_cast<size_t>(data->fast_count) * as + k] = u[k];
    }
    lambdas.push_back(lambda);
    ++data->fast_count;
  }
  const int nf = data->fast_count;
  if (nf == 0) return;
  const int count = static_cast<int>(data->watched.size());
  const int levels = static_cast<int>(data->ladder.size());
  Eigen::MatrixXd rows;
  data->rows.CopyTo(&rows);
  data->fast_reach.assign(static_cast<size_t>(levels) * count * nf, 0.0);
  for (int i = 0; i < nf; ++i) {
    const Eigen::Map<const Eigen::VectorXd> v(&data->fast_right[static_cast<size_t>(i) * as], a);
    const Eigen::VectorXd residual = (m * v - lambdas[i] * v).cwiseAbs();
    const Eigen::VectorXd read = rows.leftCols(a) * v;
    for (int j = 0; j < levels; ++j) {
      const double sigma = std::ldexp(h_, -j);
      for (int w = 0; w < count; ++w) {
        const double* reach = &data->ladder_reach[(static_cast<size_t>(j) * count + w) * as];
        double moved = 0.0;
        for (int k = 0; k < a; ++k) moved += reach[k] * residual[k];
        data->fast_reach[(static_cast<size_t>(j) * count + w) * nf + i] =
            std::abs(read[w]) + sigma * moved;
      }
    }
  }
  const size_t bytes =
      sizeof(double) * (data->fast_right.size() + data->fast_left.size() + data->fast_reach.size());
  data->bytes += bytes;
  cache_bytes_ += bytes;
}

bool ExactIntegrator::FastModesClear(PhaseData* data, int level, double sigma, int w, double margin,
                                     bool* chain_built) {
  if (!data->fast_built) BuildFastModes(data);
  const int nf = data->fast_count;
  if (nf == 0) return false;
  const int as = active_stride_;
  const int count = static_cast<int>(data->watched.size());
  const int ld = data->rows.ld();
  if (!*chain_built) {
    *chain_built = true;
    fast_rest_.assign(static_cast<size_t>(kFastOrders + 1) * stride_, 0.0);
    fast_coefficients_.assign(static_cast<size_t>(kFastOrders + 1) * nf, 0.0);
    fast_rows_.assign(static_cast<size_t>(kFastOrders + 1) * ld, 0.0);
    fast_next_.assign(as, 0.0);
    const double* x = stiff_a_.data();  // a = m v, then m r_k
    for (int k = 0; k <= kFastOrders; ++k) {
      double* rest = &fast_rest_[static_cast<size_t>(k) * stride_];
      std::copy(x, x + as, rest);
      for (int i = 0; i < nf; ++i) {
        const double* left = &data->fast_left[static_cast<size_t>(i) * as];
        const double* right = &data->fast_right[static_cast<size_t>(i) * as];
        double c = 0.0;
        for (int j = 0; j < as; ++j) c += left[j] * x[j];
        fast_coefficients_[static_cast<size_t>(k) * nf + i] = c;
        for (int j = 0; j < as; ++j) rest[j] -= c * right[j];
      }
      data->rows.Apply(rest, &fast_rows_[static_cast<size_t>(k) * ld]);
      if (k < kFastOrders) {
        data->m_active.Apply(rest, fast_next_.data());
        x = fast_next_.data();
      }
    }
  }
  // B_k = Σ_i |c_ki| (mode bound) + |R_w r_k| + σ B_{k+1}, closed at order K by |R_w| E_j |r_K|;
  // every order is a bound: the least is taken.
  const double* reach = &data->ladder_reach[(static_cast<size_t>(level) * count + w) * as];
  const double* modes = &data->fast_reach[(static_cast<size_t>(level) * count + w) * nf];
  double sum = 0.0, scale = 1.0, best = std::numeric_limits<double>::infinity();
  for (int k = 0; k <= kFastOrders; ++k) {
    for (int i = 0; i < nf; ++i) {
      sum += scale * std::abs(fast_coefficients_[static_cast<size_t>(k) * nf + i]) * modes[i];
    }
    const double* rest = &fast_rest_[static_cast<size_t>(k) * stride_];
    double closing = 0.0;
    for (int i = 0; i < active_; ++i) closing += reach[i] * std::abs(rest[i]);
    best = std::min(best, sum + scale * closing);
    sum += scale * std::abs(fast_rows_[static_cast<size_t>(k) * ld + w]);
    scale *= sigma;
  }
  return margin - best * sigma * sigma * 0.125 >= 0.0;
}

bool ExactIntegrator::StaticSurface(PhaseData* data, int w, const double* v) {
  std::fill(moving_.begin(), moving_.end(), 0);
  for (int i = 0; i < n_; ++i) {
    if (v[i] != 0.0) moving_[i / 64] |= std::uint64_t{1} << (i % 64);
  }
  if (data->reach.empty()) {
    Eigen::MatrixXd& m = m_scratch_;
    data->m_padded.CopyTo(&m);
    data->rows.CopyTo(&observe_scratch_);
    Reach(m, observe_scratch_, words_, &inputs_scratch_, &stack_scratch_, &data->reach);
  }
  return Disjoint(moving_.data(), data->reach.data() + static_cast<size_t>(w) * words_, words_);
}

bool ExactIntegrator::StiffAdvance(PhaseData* data, double t, double tau, const double* y,
                                   const double* v, const double* g0, double* y1, double* v1,
                                   double* end, double* tau_event, int* crossed) {
  if (data->ladder.empty()) BuildLadder(data);
  SimulationSummary& summary = *summary_;
  const int count = static_cast<int>(data->watched.size());
  const int search = static_cast<int>(data->ladder.size()) - 1;
  std::vector<double>&ys = stiff_y_, &vs = stiff_v_, &gs = stiff_g_, &acc = stiff_a_,
  &out = stiff_out_;
  ys.assign(y, y + stride_);
  vs.assign(v, v + stride_);
  gs.assign(g0, g0 + count);
  acc.assign(stride_, 0.0);
  out.assign(std::max<int>(2 * active_stride_, data->observe.ld()), 0.0);
  moving_.resize(words_);
  // The substeps' sum is compensated: `carry` holds what rounding y + Δy dropped (carry1 that of
  // the substep being taken). Two large speeds joined by a heavy damper change by the same amount
  // to the last bit over a short substep; without it the drift of their difference, below their
  // ulp, is lost on every substep and the link's torque stops moving (found by the driveline
  // fuzzer, input 21 0a: a surface reading that difference 3e8 times held 0.9997 of its tolerance
  // past zero while the substeps stayed at 2^-21 h until the budget ended).
  std::vector<double>& carry = stiff_carry_;
  std::vector<double>& carry1 = stiff_carry1_;
  carry.assign(stride_, 0.0);
  carry1.assign(stride_, 0.0);
  // Per watched surface, whether the bounds failed to clear it in an attempt at the substep now
  // being taken (a substep halved for it, or searched exactly).
  std::vector<char>& bounded_out = stiff_bounded_out_;
  bounded_out.assign(count, 0);
  // y1_i = ys_i + delta with the carry added, and what that rounding drops kept in carry1_i.
  auto add = [&](int i, double delta) {
    const double step = delta + carry[i];
    y1[i] = ys[i] + step;
    carry1[i] = step - (y1[i] - ys[i]);
  };
  // The same for a substep whose end the Taylor series gave (its increment as y1 − ys).
  auto carry_over = [&] {
    for (int i = 0; i < active_stride_; ++i) add(i, y1[i] - ys[i]);
  };
  auto accept = [&] {
    carry.swap(carry1);
    std::copy(y1, y1 + stride_, ys.begin());
    std::copy(v1, v1 + stride_, vs.begin());
    std::copy(end, end + count, gs.begin());
  };
  // Whether the substep about to be accepted ends the advance at a crossing: a watched surface
  // that the bounds did not clear, which ends kMaxSubstepsOnSurface substeps in a row past zero
  // but within its crossing tolerance, with its slope across. There its sign is the state's
  // rounding: a surface summing terms 1e13 times its value, whose end point the ladder's
  // propagator and the Taylor series of the same substep put on either side of −tolerance (the
  // driveline fuzzer's seeds 331, 549, 983 and 0x85002800 ended on the substep budget so). The
  // crossing is taken at the substep's end; what that may be off by, the jump of the motion at
  // the switch times the time the surface needs to cross its band, goes into the estimate
  // (Switch()).
  auto crossing_on_surface = [&](double t_end) {
    int found = -1;
    for (int w = 0; w < count && found < 0; ++w) {
      if (bounded_out[w] && end[w] < 0.0 && end[w] >= -stiff_tolerance_[w]) found = w;
    }
    std::fill(bounded_out.begin(), bounded_out.end(), 0);
    if (found >= 0) {
      data->rows.Apply(v1, out.data());
      if (!(out[found] < 0.0)) found = -1;
    }
    if (found < 0 || found != on_surface_) {
      on_surface_ = found;
      on_surface_substeps_ = found < 0 ? 0 : 1;
      return false;
    }
    if (++on_surface_substeps_ < kMaxSubstepsOnSurface) return false;
    // What the crossing may be off by: the motion of the pieces on either side differs (the
    // switch compares them, Switch()) for as long as the surface takes to cross its tolerance band.
    held_crossing_time_ = std::min(2.0 * stiff_tolerance_[found] / std::abs(out[found]),
                                   std::max(run_end_ - t_end, 0.0));
    held_crossing_v_.assign(v1, v1 + stride_);
    *crossed = found;
    on_surface_ = -1;
    on_surface_substeps_ = 0;
    return true;
  };
  double done = 0.0;
  // The level the bounds ask for (halved where they failed, one coarser after each substep taken
  // at it), apart from the level a substep takes to fit in what is left of the step: the binary
  // remainder of a step that began at a fine level must not hold the next step there (a step
  // begun at level L took L substeps climbing and a last one at L, and so did every step after).
  int wanted = std::clamp(data->level, 0, search);
  const double time_slack = 8 * kEps * std::max(std::abs(t) + tau, h_);
  long substeps = 0;
  while (done < tau) {
    if (++stiff_substeps_ > kMaxStiffSubstepsPerRun) {
      summary.message = "stiff phase sets needed more than " +
                        std::to_string(kMaxStiffSubstepsPerRun) +
                        " substeps by t = " + FormatNumber(t + done) +
                        " (last: " + model_.DescribePhases(phases_) +
                        ", |M| h = " + FormatNumber(data->norm_inf * h_) +
                        "): a switching surface stays within roundoff of zero while the stiff "
                        "motion moves; try the CVODE solver";
      return false;
    }
    if (++substeps > kMaxStiffSubsteps) {
      summary.message = "a stiff phase set (" + model_.DescribePhases(phases_) +
                        ", |M| h = " + FormatNumber(data->norm_inf * h_) + ") needs more than " +
                        std::to_string(kMaxStiffSubsteps) +
                        " substeps in one output step at t = " + FormatNumber(t + done) +
                        ": a surface stays within roundoff of switching while the motion moves "
                        "faster than the bounds can clear";
      return false;
    }
    // The coarsest level that fits in what is left; below the finest one, the rest is one
    // Taylor substep (the ladder's levels sum to any step in binary, and only the finest
    // remainder needs a propagator of its own). What is left is known to the roundoff of the
    // times (a step between output times is h to a few ulps of t, as for the cached step): a
    // level within that of it ends the step, where a relative test took the step's rounding for
    // a remainder and cut every output step into one substep per level.
    const double remaining = tau - done;
    int level = wanted;
    while (level < search && std::ldexp(h_, -level) > remaining + time_slack) ++level;
    const double sigma_level = std::ldexp(h_, -level);
    const bool taylor = sigma_level > remaining + time_slack;
    const bool last = taylor || sigma_level >= remaining - time_slack;
    const double sigma = taylor ? remaining : sigma_level;
    if (taylor) {
      ExpandStep(*data, ys.data(), vs.data(), sigma, y1, v1);
      carry_over();
    } else {
      data->ladder[level].Apply(vs.data(), out.data());
      for (int i = 0; i < active_stride_; ++i) {
        add(i, out[i]);
        v1[i] = out[active_stride_ + i];
      }
      for (int i = active_stride_; i < stride_; ++i) {
        y1[i] = ys[i];
        v1[i] = 0.0;
      }
    }
    if (!std::isfinite(numerics::MaxAbsPadded(v1, active_stride_))) return false;
    data->observe.Apply(y1, end);
    // |g''(s)| = |R_w exp(m s) m v| <= ‖R_w‖₁ G ‖m v‖∞ over the substep: the chord's error bound.
    data->m_active.Apply(vs.data(), acc.data());
    const double a_norm = numerics::MaxAbsPadded(acc.data(), active_stride_);
    const double chord = data->ladder_growth[level] * a_norm * sigma * sigma * 0.125;
    Tolerances(*data, ys.data(), y1, &stiff_tolerance_);
    stiff_candidates_.clear();
    bool chain_built = false;
    for (int w = 0; w < count; ++w) {
      const double lower = std::min(gs[w], end[w]);
      if (lower - data->row_norm[w] * chord + stiff_tolerance_[w] >= 0.0) continue;
      const double* reach =
          &data->ladder_reach[(static_cast<size_t>(level) * count + w) * active_stride_];
      double sharp = 0.0;
      for (int i = 0; i < active_; ++i) sharp += reach[i] * std::abs(acc[i]);
      if (lower - sharp * sigma * sigma * 0.125 + stiff_tolerance_[w] >= 0.0) continue;
      if (end[w] >= -stiff_tolerance_[w] && StaticSurface(data, w, vs.data())) continue;
      if (Ignored(data->watched[w].index)) continue;
      if (FastModesClear(data, level, sigma, w, lower + stiff_tolerance_[w], &chain_built)) {
        continue;
      }
      stiff_candidates_.push_back(w);
      bounded_out[w] = 1;
    }
    ++summary.steps;
    if (stiff_candidates_.empty()) {
      if (!taylor) {
        // The propagators' rounding, and the conditioning of exp(m σ) itself: the rounding of
        // m's entries (relative ε) moves the step's motion σ ‖v‖ by about ε ‖m‖ σ of it.
        const double v_norm = numerics::MaxAbsPadded(vs.data(), active_stride_);
        summary.error_estimate +=
            v_norm * (data->ladder_defect[level] + kEps * data->norm_inf * sigma * sigma);
      }
      if (crossing_on_surface(t + done + sigma)) {
        *tau_event = std::min(done + sigma, tau);  // (a last substep may pass τ by time_slack)
        data->level = wanted;
        return true;
      }
      accept();
      done = last ? tau : done + sigma;
      if (level == wanted && wanted > 0 && !last) --wanted;
      continue;
    }
    if (data->norm_inf * sigma > kSearchPieces) {  // (then level < search) halve and try again
      wanted = level + 1;
      continue;
    }
    // Short enough for the exact search on the step's Taylor series.
    if (!taylor) {
      ExpandStep(*data, ys.data(), vs.data(), sigma, y1, v1);
      carry_over();
    }
    const double resolution_s =
        kStallUlps * kEps * std::max(std::abs(t + done) + sigma, h_) / series_.dt;
    int piece = 0;
    double s = 0.0;
    ++summary.searched_steps;
    if (FindEvent(*data, stiff_candidates_, stiff_tolerance_, resolution_s, &piece, &s, crossed)) {
      *tau_event = std::min(done + (piece + s) * series_.dt, tau);
      EvaluateSeries(piece, s, y1, v1);
      data->level = wanted;
      return true;
    }
    data->observe.Apply(y1, end);
    if (crossing_on_surface(t + done + sigma)) {
      *tau_event = std::min(done + sigma, tau);
      data->level = wanted;
      return true;
    }
    accept();
    done = last ? tau : done + sigma;
  }
  data->level = wanted;
  return false;
}

MILLKIT_HOT void ExactIntegrator::ExpandStep(const PhaseData& data, const double* z,
                                             const double* v, double tau, double* z1, double* v1) {
  Series& series = series_;
  series.stride = stride_;
  series.pieces = std::max(1, static_cast<int>(std::ceil(data.series_norm * tau)));
  const PaddedMatrix& m_series = data.lowpass_apart ? data.m_series : data.m_active;
  const size_t lowpass = data.lowpass_apart ? lowpass_.size() : 0;
  series.lowpass = static_cast<int>(lowpass);
  series.data = &data;
  series.lowpass_input.resize(static_cast<size_t>(series.pieces) * lowpass * (kMaxTaylorTerms + 1));
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
    // over a piece, and a cancelling sum is no more accurate than that): the scale of the
    // components the series carries (a fast low-pass state's v must not end it early).
    const double start = BoundNorm(data, v1);
    if (start != 0.0) {
      for (int k = 1; k < kMaxTaylorTerms; ++k) {
        double* u = vector(used + k);
        m_series.Apply(u - stride_, u);
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
    // The low-pass states: their input T z over the piece is Σ_j c_j s^j, c_0 = row · z_p,
    // c_{k+1} = dt row · u_k / (k + 1), taken through the decay (LowpassAt).
    for (size_t r = 0; r < lowpass; ++r) {
      const double* row = data.lowpass_rows.data() + r * stride_;
      double* c = series.LowpassInput(p, static_cast<int>(r));
      const double* z_p = series.z_start.data() + static_cast<size_t>(p) * stride_;
      c[0] = Dot(row, z_p, active_stride_);
      const double* term = series.U(p, 0);
      for (int k = 0; k < terms; ++k, term += stride_) {
        c[k + 1] = series.dt / (k + 1) * Dot(row, term, active_stride_);
      }
    }
    if (lowpass > 0) LowpassAt(data, p, 1.0, z1, v1);
    used += terms;
  }
}

void ExactIntegrator::LowpassAt(const PhaseData& data, int p, double s, double* z,
                                double* v) const {
  const Series& series = series_;
  const int terms = series.terms[p];
  const double tau = s * series.dt;
  double* g = lowpass_weights_.data();
  for (int r = 0; r < series.lowpass; ++r) {
    const int y = lowpass_[r];
    const double z_decay = -data.lowpass_rate[r] * tau;
    // The weights of the last (z, terms) are kept: both spindles' filters and every expanded
    // full step share them (the same numbers, computed once).
    if (z_decay != weights_z_ || terms != weights_terms_) {
      numerics::ExponentialMoments(z_decay, terms, g);
      weights_decay_ = std::exp(z_decay);
      weights_z_ = z_decay;
      weights_terms_ = terms;
    }
    const double* c = series.LowpassInput(p, r);
    // Σ_j g_j c_j s^j: the input in the variable σ / (s dt).
    double sum = 0.0, power = 1.0;
    for (int j = 0; j <= terms; ++j, power *= s) sum += g[j] * c[j] * power;
    const double start = series.z_start[static_cast<size_t>(p) * stride_ + y];
    z[y] = weights_decay_ * start + tau * sum;
  }
  // y' = row · z − a y, with every low-pass state of z in place (a row reads none of them).
  for (int r = 0; r < series.lowpass; ++r) {
    const int y = lowpass_[r];
    v[y] = Dot(data.lowpass_rows.data() + static_cast<size_t>(r) * stride_, z, active_stride_) -
           data.lowpass_rate[r] * z[y];
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
  if (series.lowpass > 0) LowpassAt(*series.data, p, s, z, v);
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
  if (recorder->wants_rows()) {
    double* speed = recorder->speed(k);
    for (size_t i = 0; i < speed_index_.size(); ++i) {
      speed[i] = scale_[speed_index_[i]] * y[speed_index_[i]];
    }
    double* twist = recorder->twist(k);
    for (int l = 0; l < links; ++l) {
      twist[l] = twist_index_[l] >= 0
                     ? scale_[twist_index_[l]] * y[twist_index_[l]]
                     : torque[l] / model_.reduced_scene().links[l].stiffness_Nm_per_rad;
    }
  }
  recorder->Commit(k, torque);
}

std::string ExactIntegrator::Start(const Eigen::VectorXd& z0, const Phases& phases,
                                   SimulationSummary* summary) {
  summary_ = summary;
  const Scene& scene = model_.reduced_scene();  // outputs convert back in the recorder
  h_ = CachedStepLength(scene, options_);
  run_end_ = OutputGrid(scene, options_).back();
  scale_ = AugmentedScale(model_, h_);
  BalanceScale(model_, &scale_);
  inverse_scale_ = scale_.cwiseInverse();
  const int links = static_cast<int>(scene.links.size());
  for (size_t i = 0; i < scene.masses.size(); ++i) {
    speed_index_.push_back(model_.SpeedIndex(model_.reduction().group_of_mass[i]));
  }
  for (int l = 0; l < links; ++l) {
    const int f = model_.FlexibleIndexOf(l);
    twist_index_.push_back(f >= 0 ? model_.TwistIndex(f) : -1);
  }
  phases_ = phases;
  data_ = Data(phases_);

  // Scaled state y and its derivative v (padded with zeros), the same at the end of a step, and
  // the watched surfaces' values at the step's start (g0) and end (`end_` holds [g; link
  // torques]); their slopes (dg0, dg1) only when a step needs them.
  const int surfaces = model_.surface_count();
  const int max_ld = PaddedMatrix::Padded(2 * stride_ + surfaces + links);
  y_.assign(stride_, 0.0);
  v_.assign(stride_, 0.0);
  y1_.assign(stride_, 0.0);
  v1_.assign(stride_, 0.0);
  for (auto* vector : {&g0_, &dg0_, &end_, &dg1_, &out_, &accel_}) vector->assign(max_ld, 0.0);
  for (int i = 0; i < n_; ++i) y_[i] = z0[i] / scale_[i];
  unscaled_.resize(n_);
  moving_scratch_.assign(words_, 0);
  slack_.assign(surfaces, 0.0);
  Refresh();
  data_->observe.Apply(y_.data(), end_.data());
  return {};
}

void ExactIntegrator::Refresh() {  // v, g0 and ‖v‖ from y in the current phases
  data_->m_padded.Apply(y_.data(), v_.data());
  data_->rows.Apply(y_.data(), g0_.data());
  v_norm_ = BoundNorm(*data_, v_.data());
}

MILLKIT_HOT void ExactIntegrator::AdvanceLeg(double t, const Leg& leg, LegEnd* leg_end) {
  PhaseData* data = data_;
  std::vector<double>&y = y_, &v = v_, &y1 = y1_, &v1 = v1_, &g0 = g0_, &dg0 = dg0_, &end = end_,
  &dg1 = dg1_, &out = out_;
  ignored_ = leg.ignored;
  held_crossing_time_ = 0.0;  // (a crossing taken on its surface that did not switch)
  const double t_grid = leg.output_time;
  const double target = leg.target;
  const double tau = target - t;
  // The cached step serves a step between output times whose gap is h to roundoff of the times
  // themselves (the state lands a few ulps of t off: as exact as t can be stated).
  const bool full_step = leg.from_output && leg.at_output &&
                         std::abs(tau - h_) <= 8 * kEps * std::max(std::abs(t_grid), h_);
  const int count = static_cast<int>(data->watched.size());
  auto fail = [&](std::string message) {
    leg_end->kind = LegEnd::Kind::kFailed;
    leg_end->message = std::move(message);
  };
  // event: a switching event was located within the step; y1, v1 hold the state there.
  double tau_event = 0.0;
  int crossed = -1;
  bool event = false;
  if (data->series_norm * tau > kMaxTaylorPieces) {
    event = StiffAdvance(data, t, tau, y.data(), v.data(), g0.data(), y1.data(), v1.data(),
                         end.data(), &tau_event, &crossed);
    if (!summary_->message.empty()) return fail(summary_->message);
    if (!event && !std::isfinite(numerics::MaxAbsPadded(v1.data(), active_stride_))) {
      return fail("state became non-finite at t = " + std::to_string(t));
    }
  } else {
    if (full_step && !data->has_step && ++data->full_steps >= kStepsBeforeCaching) {
      BuildStep(data);
    }
    bool expanded = false;
    double growth = data->growth;
    if (full_step && data->has_step) {
      data->step.Apply(v.data(), out.data());
      for (int i = 0; i < active_stride_; ++i) {
        y1[i] = y[i] + out[i];
        v1[i] = out[active_stride_ + i];
      }
      for (int i = active_stride_; i < stride_; ++i) y1[i] = y[i];  // (v1 stays zero there)
      summary_->error_estimate += data->defect;
    } else {
      ExpandStep(*data, y.data(), v.data(), tau, y1.data(), v1.data());
      expanded = true;
      growth = std::exp(std::min(data->series_norm * tau, 700.0));
      if (tau <= h_) growth = std::min(growth, data->growth);  // (sup over s <= h)
    }
    ++summary_->steps;
    // Non-finite states show in v first (y1 = y + Φ v).
    const double v1_norm = numerics::MaxAbsPadded(v1.data(), active_stride_);  // zero beyond
    if (!std::isfinite(v1_norm)) return fail("state became non-finite at t = " + std::to_string(t));
    data->observe.Apply(y1.data(), end.data());

    // Which watched surfaces can cross within the step: the bounds first, exact work after. The
    // surfaces are signed (>= 0 on the watched side). The first pass is branch-free over all of
    // them with the smallest tolerance (state size 1): the chord between the ends is off g by at
    // most max|g''| τ²/8. The surfaces it does not clear get their slopes and the tighter tiers.
    const double l_factor = growth * v_norm_ * tau * tau * 0.125;
    const double c_factor = growth * v_norm_ * tau * tau * tau * tau * (1.0 / 24.0);
    double least = 0.0;
    {
      const double* __restrict a0 = g0.data();
      const double* __restrict a1 = end.data();
      const double* __restrict bound2 = data->bound2.data();
      const double* __restrict tol = data->tolerance.data();
      double* __restrict out_slack = slack_.data();
      for (int w = 0; w < count; ++w) {
        const double lower = a0[w] < a1[w] ? a0[w] : a1[w];
        out_slack[w] = lower - bound2[w] * l_factor + tol[w];
        least = out_slack[w] < least ? out_slack[w] : least;
      }
    }
    const bool any = least < 0.0;
    candidates_.clear();
    if (any) {
      data->rows.Apply(v.data(), dg0.data());
      data->rows.Apply(v1.data(), dg1.data());
      Tolerances(*data, y.data(), y1.data(), &tolerance_);
      bool moving_known = false;
      double accel_chord = -1.0;  // ‖R_w‖₁ times it bounds the chord's error (on first need)
      tolerance_.resize(count);
      for (int w = 0; w < count; ++w) {
        if (slack_[w] >= 0.0) continue;
        if (Ignored(data->watched[w].index)) continue;
        if (end[w] < -tolerance_[w]) {
          candidates_.push_back(w);
          continue;
        }
        const double a0 = g0[w], a1 = end[w], b0 = dg0[w] * tau, b1 = dg1[w] * tau;
        const double c = data->bound3[w] * c_factor;
        if (QuickMinimum(a0, b0, a1, b1, c) >= -tolerance_[w]) continue;
        // The chord bound again with the acceleration itself: |g''(s)| = |R_w exp(m s) m v| <=
        // ‖R_w‖₁ growth ‖m v‖∞, far below bound2 growth ‖v‖∞ once a damped fast mode has decayed.
        if (accel_chord < 0.0) {
          (data->lowpass_apart ? data->m_series : data->m_active).Apply(v.data(), accel_.data());
          accel_chord =
              growth * numerics::MaxAbsPadded(accel_.data(), active_stride_) * tau * tau * 0.125;
        }
        if (std::min(a0, a1) - data->row_norm[w] * accel_chord + tolerance_[w] >= 0.0) continue;
        if (!moving_known) {
          std::fill(moving_scratch_.begin(), moving_scratch_.end(), 0);
          for (int i = 0; i < n_; ++i) {
            if (v[i] != 0.0) moving_scratch_[i / 64] |= std::uint64_t{1} << (i % 64);
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
        if (Disjoint(moving_scratch_.data(), data->reach.data() + static_cast<size_t>(w) * words_,
                     words_)) {
          continue;
        }
        if (EnvelopeMinimum(a0, b0, a1, b1, c) < -tolerance_[w]) candidates_.push_back(w);
      }
    }

    if (!candidates_.empty()) {
      if (!expanded) ExpandStep(*data, y.data(), v.data(), tau, y1.data(), v1.data());
      const double resolution_s = kStallUlps * kEps * std::max(std::abs(t) + tau, h_) / series_.dt;
      int piece = 0;
      double s = 0.0;
      ++summary_->searched_steps;
      if (FindEvent(*data, candidates_, tolerance_, resolution_s, &piece, &s, &crossed)) {
        tau_event = (piece + s) * series_.dt;
        EvaluateSeries(piece, s, y1.data(), v1.data());
        event = true;
      } else if (!expanded) {  // the series' end replaced the cached step's: observe that one
        data->observe.Apply(y1.data(), end.data());
      }
    }
  }  // Taylor or cached step

  if (event) {
    const Model::WatchedSurface surface = data->watched[crossed];
    leg_end->kind = LegEnd::Kind::kEvent;
    leg_end->t = t + tau_event;
    leg_end->elapsed = tau_event;
    leg_end->crossed.assign(1, {surface.index, -surface.side});
    return;
  }
  y.swap(y1);
  v.swap(v1);
  Copy(end.data(), count, g0.data());
  v_norm_ = BoundNorm(*data, v.data());
  leg_end->kind = LegEnd::Kind::kReached;
  leg_end->t = target;
  leg_end->elapsed = tau;
}

void ExactIntegrator::EventMotion(Eigen::VectorXd* z, std::vector<Eigen::VectorXd>* derivatives) {
  // Sides of the other surfaces from the motion before the event (Model::Classify): its
  // derivatives z', z'', ... up to the state's size, as a motion from rest may start at any order.
  z->resize(n_);
  for (int i = 0; i < n_; ++i) (*z)[i] = scale_[i] * y1_[i];
  derivatives->resize(n_);
  std::copy(v1_.begin(), v1_.end(), out_.begin());
  for (int order = 0; order < n_; ++order) {
    if (order > 0) {
      std::fill(dg1_.begin(), dg1_.end(), 0.0);
      data_->m_active.Apply(out_.data(), dg1_.data());
      std::copy(dg1_.begin(), dg1_.begin() + active_stride_, out_.begin());
    }
    Eigen::VectorXd& derivative = (*derivatives)[order];
    derivative.resize(n_);
    for (int i = 0; i < n_; ++i) derivative[i] = scale_[i] * out_[i];
    if (order >= 2 && derivative.cwiseAbs().maxCoeff() == 0.0) {
      // Every higher order is zero too: none may be left over from an earlier event.
      derivatives->resize(order + 1);
      break;
    }
  }
}

void ExactIntegrator::Switch(const Phases& phases, double /*t*/) {
  on_surface_ = -1;
  on_surface_substeps_ = 0;
  y_.swap(y1_);
  phases_ = phases;
  data_ = Data(phases_);
  Refresh();
  if (held_crossing_time_ > 0.0) {
    double jump = 0.0;
    for (int i = 0; i < active_; ++i) jump = std::max(jump, std::abs(v_[i] - held_crossing_v_[i]));
    summary_->error_estimate += jump * held_crossing_time_;
    held_crossing_time_ = 0.0;
  }
}

void ExactIntegrator::ApplyBreakpoint(double breakpoint, double /*t*/) {
  // Inputs from their right limit at the breakpoint itself: a breakpoint snapped onto a sample
  // time a few ulps away must not be read as still inside the ramp before it.
  for (int i = 0; i < n_; ++i) unscaled_[i] = scale_[i] * y_[i];
  model_.SetForcing(breakpoint, &unscaled_);
  for (int i = 0; i < n_; ++i) y_[i] = unscaled_[i] / scale_[i];
  Refresh();
  data_->observe.Apply(y_.data(), end_.data());
}

}  // namespace

double ExactStepLength(const Model& model, const SimulationOptions& options) {
  return CachedStepLength(model.reduced_scene(), options);
}

Eigen::VectorXd ExactScale(const Model& model, double step) {
  Eigen::VectorXd scale = AugmentedScale(model, step);
  BalanceScale(model, &scale);
  return scale;
}

std::unique_ptr<ModeIntegrator> MakeExactIntegrator(const Model& model,
                                                    const SimulationOptions& options) {
  return std::make_unique<ExactIntegrator>(model, options);
}

}  // namespace millkit::driveline
