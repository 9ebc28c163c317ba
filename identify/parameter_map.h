// The three coordinates of a free scene parameter (identify/ internal):
//   physical value p in [lower, upper] (the scene's units);
//   unit coordinate u in [0, 1], what the scan samples, the finite differences step in and the
//     covariance is computed over;
//   angle φ with u = (1 + sin φ)/2, what Levenberg–Marquardt moves: every φ is inside the bounds,
//     so Ceres needs no bound constraints (with bounds it runs a projected search that evaluates
//     the whole Jacobian at every trial step, ten times the simulations).
// A scale parameter (damping, stiffness, inertia) whose bounds are positive and span a factor of
// kLogSpan or more is mapped on a log scale, u = ln(p/lower) / ln(upper/lower): a damping bounded
// by [d/10, 10 d] then has its prior in the middle, and equal steps in u are equal ratios, which
// is how a damping's effect on the record scales (decay rate ∝ d). Gaps, gap positions and the
// bite time move impacts in time, linearly, and keep a linear map.
#pragma once

#include <algorithm>
#include <cmath>

#include "millkit/identify/fit_config.h"

namespace millkit::identify {

inline constexpr double kLogSpan = 4.0;
// A unit coordinate within this of 0 or 1 is at its bound: Levenberg–Marquardt moves φ, and
// u = (1 + sin φ)/2 is flat at a bound, so a fit pressed against one stops a few 1e-9 short.
inline constexpr double kAtBound = 1e-6;

class ParameterMap {
 public:
  ParameterMap() = default;
  explicit ParameterMap(const FreeParameter& free) : lower_(free.lower), upper_(free.upper) {
    using Kind = driveline::SceneParameter::Kind;
    const auto kind = free.parameter.kind;
    const bool scale = kind == Kind::kDamping || kind == Kind::kStiffness || kind == Kind::kInertia;
    log_ = scale && lower_ > 0.0 && upper_ >= kLogSpan * lower_;
    if (log_) log_span_ = std::log(upper_ / lower_);
  }

  bool log_scale() const { return log_; }
  double Physical(double u) const {
    return log_ ? lower_ * std::exp(u * log_span_) : lower_ + u * (upper_ - lower_);
  }
  double Unit(double p) const {
    return log_ ? std::log(p / lower_) / log_span_ : (p - lower_) / (upper_ - lower_);
  }
  // dp/du at u.
  double PhysicalPerUnit(double u) const {
    return log_ ? Physical(u) * log_span_ : upper_ - lower_;
  }

  static double UnitFromAngle(double phi) { return 0.5 * (1.0 + std::sin(phi)); }
  static double AngleFromUnit(double u) { return std::asin(std::clamp(2.0 * u - 1.0, -1.0, 1.0)); }
  static double UnitPerAngle(double phi) { return 0.5 * std::cos(phi); }

 private:
  double lower_ = 0.0;
  double upper_ = 1.0;
  bool log_ = false;
  double log_span_ = 0.0;
};

}  // namespace millkit::identify
