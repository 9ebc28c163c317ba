#include "millkit/leveller/strip_mechanics.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "io/invariant.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::leveller {
namespace {

constexpr double kFullyPlasticRatio = 1.5;  // Ms/Mw of a rectangle
// Moments are kept this far inside ±Ms/Mw, where the curvature is finite.
constexpr double kMomentMargin = 1e-9;
// Forward-difference step of the Newton Jacobian (moment ratio).
constexpr double kJacobianStep = 1e-7;

// ∫_0^u g(v) dv for the inverse skeleton g (even in u).
double SkeletonIntegral(double u) {
  const double a = std::abs(u);
  if (a <= 1.0) return 0.5 * a * a;
  return kFullyPlasticRatio - std::sqrt(3.0 - 2.0 * a);
}

}  // namespace

double MomentRatio(double c) {
  const double a = std::abs(c);
  if (a <= 1.0) return c;
  return std::copysign(kFullyPlasticRatio - 0.5 / (a * a), c);
}

double CurvatureRatio(double m) {
  const double a = std::abs(m);
  if (a <= 1.0) return m;
  if (a >= kFullyPlasticRatio) return std::copysign(std::numeric_limits<double>::infinity(), m);
  return std::copysign(1.0 / std::sqrt(3.0 - 2.0 * a), m);
}

double ResidualCurvatureRatio(double c) { return c - MomentRatio(c); }

double CurvatureRatioForPlasticDepth(double plastic_ratio) { return 1.0 / (1.0 - plastic_ratio); }

double CollisionLimitIntermesh_mm(double roll_diameter_mm, double thickness_mm, double pitch_mm) {
  const double reach = roll_diameter_mm + thickness_mm;
  return roll_diameter_mm - std::sqrt(reach * reach - 0.25 * pitch_mm * pitch_mm);
}

// ---------------------------------------------------------------------------------------------

void MasingSection::MoveTo(double target) {
  if (target == m_) return;
  const int direction = target > m_ ? 1 : -1;
  if (direction_ != 0 && direction != direction_) turns_.push_back({m_, c_});
  direction_ = direction;
  auto branch_c = [this](double m) {
    if (turns_.empty()) return CurvatureRatio(m);
    const Turn& r = turns_.back();
    return r.c + 2.0 * CurvatureRatio(0.5 * (m - r.m));
  };
  auto branch_integral = [this](double ma, double mb) {  // ∫ C dm on the current branch
    if (turns_.empty()) return SkeletonIntegral(mb) - SkeletonIntegral(ma);
    const Turn& r = turns_.back();
    return r.c * (mb - ma) +
           4.0 * (SkeletonIntegral(0.5 * (mb - r.m)) - SkeletonIntegral(0.5 * (ma - r.m)));
  };
  auto advance = [&](double mb) {
    const double cb = branch_c(mb);
    MILLKIT_CHECK(std::isfinite(cb), "MasingSection: moment at or beyond the fully plastic moment");
    work_ += mb * cb - m_ * c_ - branch_integral(m_, mb);  // ∫ m dC = [m C] − ∫ C dm
    m_ = mb;
    c_ = cb;
  };
  while (true) {
    if (!turns_.empty()) {
      const std::size_t n = turns_.size();
      const double limit = n == 1 ? -turns_[0].m : turns_[n - 2].m;
      if ((target - limit) * direction > 0.0) {
        advance(limit);
        turns_.resize(n == 1 ? 0 : n - 2);  // loop closed: back on the older branch
        continue;
      }
    }
    advance(target);
    return;
  }
}

double MasingSection::CurvatureAt(double moment_ratio) const {
  MasingSection copy = *this;
  copy.MoveTo(moment_ratio);
  return copy.c_;
}

StripPass SimulateStripPass(const Strip& strip, double pitch_mm, const std::array<double, 7>& m,
                            int samples) {
  MILLKIT_CHECK(samples >= 2 && samples % 2 == 0, "Simpson's rule needs an even sample count");
  const double a = 0.5 * pitch_mm;                                   // mm
  const double kappa_t = ElasticLimitCurvature_per_m(strip) * 1e-3;  // 1/mm
  const double ds = a / samples;
  MasingSection section;
  StripPass pass;
  std::array<double, 6> i0{}, i1{};  // ∫ κ ds and ∫ s κ ds over each span
  for (int j = 0; j < 6; ++j) {
    pass.curvature_ratio[j] = section.curvature();
    double sum0 = 0.0;
    double sum1 = 0.0;
    for (int k = 0; k <= samples; ++k) {
      const double s = k * ds;
      if (k > 0) section.MoveTo(m[j] + (m[j + 1] - m[j]) * (static_cast<double>(k) / samples));
      const double kappa = kappa_t * section.curvature();
      const double w = (k == 0 || k == samples) ? 1.0 : (k % 2 == 1 ? 4.0 : 2.0);
      sum0 += w * kappa;
      sum1 += w * s * kappa;
    }
    i0[j] = sum0 * ds / 3.0;
    i1[j] = sum1 * ds / 3.0;
  }
  pass.curvature_ratio[6] = section.curvature();
  for (int i = 1; i <= 5; ++i) {
    pass.second_difference_mm[i] = 0.5 * (i1[i - 1] + a * i0[i] - i1[i]);
  }
  pass.exit_residual_curvature_ratio = section.curvature();
  pass.work_per_length_N =
      section.work() * ElasticLimitMoment_Nm(strip) * ElasticLimitCurvature_per_m(strip);
  return pass;
}

void SetpointOptions::Validate() const {
  if (!(entry_plastic_ratio >= 0.0 && entry_plastic_ratio < 1.0)) {
    throw InputError("entry_plastic_ratio must be in [0, 1) (got " +
                     FormatNumber(entry_plastic_ratio) + ")");
  }
  const double entry_c = CurvatureRatioForPlasticDepth(entry_plastic_ratio);
  if (exit == ExitCondition::kFixedCurvature &&
      !(exit_curvature_ratio > 0.0 && exit_curvature_ratio <= entry_c)) {
    throw InputError("exit_curvature_ratio must be in (0, entry curvature ratio " +
                     FormatNumber(entry_c) + "] (got " + FormatNumber(exit_curvature_ratio) + ")");
  }
  if (!(tolerance_mm > 0.0)) throw InputError("setpoint tolerance_mm must be > 0");
  if (max_iterations < 1) throw InputError("setpoint max_iterations must be >= 1");
}

std::string SetpointSummary::BriefReport() const {
  return std::string(converged ? "CONVERGED" : "NO CONVERGENCE") + ", " +
         std::to_string(iterations) + " Newton iterations, contact residual " +
         FormatNumber(residual_mm) + " mm" + (message.empty() ? "" : " (" + message + ")");
}

namespace {

// Exit curvature ratios scanned (from the entry value down) to bracket a flat exit.
constexpr int kExitScanPoints = 48;
constexpr double kExitScanLowest = 0.02;
constexpr int kExitBisections = 80;

struct InnerSolve {
  Eigen::Vector3d x;  // m3, m4, m5
  double residual_mm = 0.0;
  int iterations = 0;
  bool converged = false;
  bool stalled = false;
};

// Newton on (m3, m4, m5) for fixed m2, m6: contact conditions at rolls 3, 4, 5 with collinear
// upper rolls (see the header).
InnerSolve SolveInner(const Strip& strip, double pitch_mm, double m2, double m6,
                      const Eigen::Vector3d& start, double tolerance_mm, int max_iterations) {
  const double limit = kFullyPlasticRatio - kMomentMargin;
  auto residual = [&](const Eigen::Vector3d& x) {
    const auto d = SimulateStripPass(strip, pitch_mm, {0.0, m2, x[0], x[1], x[2], m6, 0.0})
                       .second_difference_mm;
    return Eigen::Vector3d(d[3] - 0.5 * (d[1] + d[5]), d[2] + 0.25 * (3.0 * d[1] + d[5]),
                           d[4] + 0.25 * (d[1] + 3.0 * d[5]));
  };
  InnerSolve out;
  out.x = start;
  Eigen::Vector3d f = residual(out.x);
  for (out.iterations = 0; out.iterations < max_iterations; ++out.iterations) {
    if (f.lpNorm<Eigen::Infinity>() <= tolerance_mm) break;
    Eigen::Matrix3d jacobian;
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d xp = out.x;
      const double step = out.x[c] > 0.0 ? -kJacobianStep : kJacobianStep;  // towards zero
      xp[c] += step;
      jacobian.col(c) = (residual(xp) - f) / step;
    }
    const Eigen::Vector3d dx = jacobian.fullPivLu().solve(-f);
    double lambda = 1.0;
    bool improved = false;
    while (lambda > 1e-6) {
      const Eigen::Vector3d trial = out.x + lambda * dx;
      if (trial.cwiseAbs().maxCoeff() <= limit) {
        const Eigen::Vector3d ft = residual(trial);
        if (ft.lpNorm<Eigen::Infinity>() < f.lpNorm<Eigen::Infinity>()) {
          out.x = trial;
          f = ft;
          improved = true;
          break;
        }
      }
      lambda *= 0.5;
    }
    if (!improved) {
      out.stalled = true;
      break;
    }
  }
  out.residual_mm = f.lpNorm<Eigen::Infinity>();
  out.converged = out.residual_mm <= tolerance_mm;
  return out;
}

Eigen::Vector3d LinearStart(double m2, double m6) {
  return {-(m2 + 0.25 * (m6 - m2)), m2 + 0.5 * (m6 - m2), -(m2 + 0.75 * (m6 - m2))};
}

}  // namespace

StripSetpoint ComputeStripSetpoint(const Strip& strip, const MachineData& machine,
                                   const SetpointOptions& options) {
  ValidateStrip(strip, "strip");
  options.Validate();
  const double h = strip.thickness_mm;
  const double c2 = CurvatureRatioForPlasticDepth(options.entry_plastic_ratio);
  const double m2 = MomentRatio(c2);
  const double a = 0.5 * machine.pitch_mm;
  // Residual curvature ratio → mm: the plunge that curvature makes over one roll spacing.
  const double curvature_scale_mm = ElasticLimitCurvature_per_m(strip) * 1e-3 * a * a;
  StripSetpoint out;
  auto& summary = out.summary;

  double m6 = 0.0;
  InnerSolve inner;
  if (options.exit == ExitCondition::kFixedCurvature) {
    m6 = MomentRatio(options.exit_curvature_ratio);
    inner = SolveInner(strip, machine.pitch_mm, m2, m6, LinearStart(m2, m6), options.tolerance_mm,
                       options.max_iterations);
    summary.iterations = inner.iterations;
    summary.converged = inner.converged;
    summary.residual_mm = inner.residual_mm;
    if (inner.stalled) summary.message = "line search failed at the fully plastic limit";
  } else {
    // Flat exit: the exit residual curvature as a function of C6 (each point an inner solve);
    // the largest root below the entry curvature is bracketed by a scan and refined by bisection.
    auto exit_residual = [&](double c6, InnerSolve* solve) {
      const double m = MomentRatio(c6);
      *solve = SolveInner(strip, machine.pitch_mm, m2, m, LinearStart(m2, m), options.tolerance_mm,
                          options.max_iterations);
      summary.iterations += solve->iterations;
      if (!solve->converged) return std::numeric_limits<double>::quiet_NaN();
      return SimulateStripPass(strip, machine.pitch_mm,
                               {0.0, m2, solve->x[0], solve->x[1], solve->x[2], m, 0.0})
                 .exit_residual_curvature_ratio *
             curvature_scale_mm;
    };
    double hi = c2;
    InnerSolve hi_solve;
    double f_hi = exit_residual(hi, &hi_solve);
    bool bracketed = false;
    double lo = hi;
    double f_lo = f_hi;
    for (int k = 1; k <= kExitScanPoints && !bracketed; ++k) {
      const double c = c2 - (c2 - kExitScanLowest) * k / kExitScanPoints;
      InnerSolve solve;
      const double f = exit_residual(c, &solve);
      if (std::isfinite(f) && std::isfinite(f_hi) && (f <= 0.0) != (f_hi <= 0.0)) {
        lo = c;
        f_lo = f;
        bracketed = true;
      } else {
        hi = c;
        f_hi = f;
      }
    }
    if (!bracketed) {
      summary.message = "no flat exit below the entry curvature ratio " + FormatNumber(c2);
      inner = SolveInner(strip, machine.pitch_mm, m2, 1.0, LinearStart(m2, 1.0),
                         options.tolerance_mm, options.max_iterations);
      m6 = 1.0;
      summary.residual_mm = inner.residual_mm;
    } else {
      double c_mid = lo;
      for (int k = 0; k < kExitBisections; ++k) {
        c_mid = 0.5 * (lo + hi);
        const double f = exit_residual(c_mid, &inner);
        if (!std::isfinite(f)) {
          summary.message = "inner solve failed while bracketing the flat exit";
          break;
        }
        if (std::abs(f) <= options.tolerance_mm || hi - lo < 1e-15) break;
        if ((f <= 0.0) == (f_lo <= 0.0)) {
          lo = c_mid;
          f_lo = f;
        } else {
          hi = c_mid;
        }
      }
      m6 = MomentRatio(c_mid);
      const double exit_mm = exit_residual(c_mid, &inner);
      summary.residual_mm = std::max(inner.residual_mm, std::abs(exit_mm));
      summary.converged = inner.converged && std::abs(exit_mm) <= 1e3 * options.tolerance_mm;
    }
  }
  Eigen::Vector3d x = inner.x;
  auto moments = [&](const Eigen::Vector3d& v) {
    return std::array<double, 7>{0.0, m2, v[0], v[1], v[2], m6, 0.0};
  };

  const auto m = moments(x);
  const StripPass pass = SimulateStripPass(strip, machine.pitch_mm, m);
  const auto& d = pass.second_difference_mm;
  out.intermesh_mm[0] = d[1] - h;
  out.intermesh_mm[2] = d[5] - h;
  out.intermesh_mm[1] = 0.5 * (out.intermesh_mm[0] + out.intermesh_mm[2]);
  out.moment_ratio = m;
  const double mw = ElasticLimitMoment_Nm(strip);
  for (int i = 0; i < 7; ++i) out.moments_Nm[i] = std::abs(m[i]) * mw;
  out.forces_kN = RollForcesFromMoments_kN(out.moments_Nm, machine.pitch_mm);
  out.total_force_kN = Sum(out.forces_kN);
  out.straightening_torque_kNm =
      pass.work_per_length_N * 0.5 * machine.roll_diameter_mm * 1e-3 * 1e-3;
  out.power_kW = DrivePower_kW(out.straightening_torque_kNm, out.total_force_kN, machine);
  out.exit_residual_curvature_ratio = pass.exit_residual_curvature_ratio;
  out.collision_limit_mm =
      CollisionLimitIntermesh_mm(machine.roll_diameter_mm, h, machine.pitch_mm);
  return out;
}

}  // namespace millkit::leveller
