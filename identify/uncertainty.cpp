#include "identify/uncertainty.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "identify/multistart.h"
#include "millkit/io/number_format.h"

namespace millkit::identify {
namespace {

// Singular values below this fraction of the largest are the null space of the covariance
// (eigenvalues of JᵀJ below 1e-14 of the largest: roundoff of the finite differences).
constexpr double kCovarianceCut = 1e-7;

// A quantity whose column moves the weighted residuals by less than this many noise units over
// its whole bound range (1 in unit coordinates) is held where it is: in the linearisation at the
// minimum, any value in its bounds moves the others' fit by less than this many standard errors.
constexpr double kNegligibleEffect = 0.01;

// The fitted quantities the record depends on (Covariance). Scaled to unit length like the
// others, a negligible column is its roundoff (or a trace of an effect) pointing anywhere, and
// takes from the others whatever part of their columns it points along: their standard errors
// then depend on where it is held (up to 2.2 times over 30 records of the balanced line).
// A fitted quantity's standard error in unit coordinates were every other one known:
// noise / ‖its Jacobian column‖ (infinite for a column the record does not see). Above
// FitOptions::unidentifiable_fraction the record hardly depends on it.
double AloneStandardError(double column_norm, double noise_scale) {
  return column_norm > 0.0 ? noise_scale / column_norm : std::numeric_limits<double>::infinity();
}

std::vector<int> Informative(const Eigen::MatrixXd& jacobian, const std::vector<int>& fitted,
                             double noise_scale) {
  std::vector<int> informative;
  for (const int j : fitted) {
    if (jacobian.col(j).norm() >= kNegligibleEffect * noise_scale) informative.push_back(j);
  }
  return informative;
}

}  // namespace

Eigen::MatrixXd Covariance(const Eigen::MatrixXd& jacobian, const std::vector<int>& all_fitted,
                           double noise_scale) {
  const int size = static_cast<int>(jacobian.cols());
  const std::vector<int> fitted = Informative(jacobian, all_fitted, noise_scale);
  Eigen::MatrixXd reduced(jacobian.rows(), fitted.size());
  for (size_t j = 0; j < fitted.size(); ++j) reduced.col(j) = jacobian.col(fitted[j]);
  // Column scaling first: quantities in different units must not cut each other's singular
  // values.
  Eigen::VectorXd norms(fitted.size());
  for (int j = 0; j < reduced.cols(); ++j) {
    norms(j) = reduced.col(j).norm();
    if (norms(j) > 0.0) reduced.col(j) /= norms(j);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(reduced, Eigen::ComputeThinV);
  const auto& sv = svd.singularValues();
  Eigen::VectorXd inverse_square = Eigen::VectorXd::Zero(sv.size());
  for (int k = 0; k < sv.size(); ++k) {
    if (sv(k) > kCovarianceCut * sv(0)) inverse_square(k) = 1.0 / (sv(k) * sv(k));
  }
  const Eigen::MatrixXd& v = svd.matrixV();
  Eigen::MatrixXd scaled = v * inverse_square.asDiagonal() * v.transpose();
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Zero(size, size);
  for (size_t a = 0; a < fitted.size(); ++a) {
    for (size_t b = 0; b < fitted.size(); ++b) {
      const double na = norms(a) > 0.0 ? norms(a) : std::numeric_limits<double>::quiet_NaN();
      const double nb = norms(b) > 0.0 ? norms(b) : std::numeric_limits<double>::quiet_NaN();
      covariance(fitted[a], fitted[b]) = scaled(a, b) / (na * nb) * noise_scale * noise_scale;
    }
  }
  // A held quantity: its variance were every other one known (noise / ‖column‖)², uncorrelated.
  for (const int j : all_fitted) {
    if (std::find(fitted.begin(), fitted.end(), j) != fitted.end()) continue;
    const double norm = jacobian.col(j).norm();
    covariance(j, j) = norm > 0.0 ? noise_scale * noise_scale / (norm * norm)
                                  : std::numeric_limits<double>::quiet_NaN();
  }
  return covariance;
}

void FlagUnidentifiable(const FitModel& model, const Eigen::MatrixXd& jacobian,
                        const std::vector<int>& all_fitted, double noise_scale,
                        const FitOptions& options, FitResult* result) {
  const int p = model.parameters();
  // The collinearity test on the columns the record depends on, as the covariance (a negligible
  // column fails the first test below on its own).
  const std::vector<int> fitted = Informative(jacobian, all_fitted, noise_scale);
  Eigen::MatrixXd scaled(jacobian.rows(), fitted.size());
  for (size_t j = 0; j < fitted.size(); ++j) {
    const double norm = jacobian.col(fitted[j]).norm();
    scaled.col(j) = norm > 0.0 ? Eigen::VectorXd(jacobian.col(fitted[j]) / norm)
                               : Eigen::VectorXd(jacobian.col(fitted[j]));
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled, Eigen::ComputeThinV);
  const auto& sv = svd.singularValues();
  result->summary.reciprocal_condition =
      sv.size() > 0 && sv(0) > 0.0 ? sv(sv.size() - 1) / sv(0) : 0.0;
  for (size_t q = 0; q < all_fitted.size(); ++q) {
    if (all_fitted[q] >= p) continue;  // gains and offsets are reported, not flagged
    const int s = all_fitted[q];
    const double norm = jacobian.col(s).norm();
    const auto in_svd = std::find(fitted.begin(), fitted.end(), s);
    auto& estimate = result->parameters[s];
    // On the scale the parameter is fitted on (unit coordinates: a log scale for a scale
    // parameter with wide bounds), where the bound range is 1: a damping of 1e4 ± 2e4 near the
    // bottom of [1e4, 1e6] spans most of its range, however small 2e4 is against 1e6.
    const ParameterMap& map = model.slot(s).map;
    const double per_unit = map.PhysicalPerUnit(model.Unit(s, estimate.value));
    const double limit = options.unidentifiable_fraction;
    const auto range = [&] {
      return ShortNumber(options.unidentifiable_fraction) + " of its bound range [" +
             ShortNumber(estimate.lower) + ", " + ShortNumber(estimate.upper) + "]" +
             (map.log_scale() ? " on the log scale it is fitted on" : "");
    };
    const double alone = AloneStandardError(norm, noise_scale);
    if (!(alone <= limit) || in_svd == fitted.end()) {
      estimate.identifiable = false;
      estimate.why_not =
          "the record hardly depends on it: even with every other quantity known "
          "its standard error would be " +
          ShortNumber(alone * per_unit) + ", more than " + range();
      continue;
    }
    const auto j = in_svd - fitted.begin();
    for (int k = 0; k < sv.size(); ++k) {
      if (sv(k) < options.rank_tolerance * sv(0) && std::abs(svd.matrixV()(j, k)) > 0.1) {
        estimate.identifiable = false;
        estimate.why_not = "the Jacobian is rank-deficient in its direction (singular value " +
                           ShortNumber(sv(k) / sv(0)) + " of the largest): it trades off " +
                           "against other parameters";
      }
    }
    if (estimate.identifiable && !(estimate.standard_error / per_unit <= limit)) {
      estimate.identifiable = false;
      estimate.why_not =
          "its standard error " + ShortNumber(estimate.standard_error) + " exceeds " + range();
    }
  }
}

std::vector<ProfileProbe> ProfileProbes(const FitModel& model, const std::vector<double>& u,
                                        const FitOptions& options) {
  const int points = options.profile_points;
  std::vector<ProfileProbe> all = MapOverCopies<ProfileProbe>(
      model, options.threads, model.parameters() * points, [&](const FitModel& copy, int i) {
        ProfileProbe probe{i / points, u, 0.0};
        probe.u[probe.slot] = (i % points + 0.5) / points;
        probe.cost = copy.ProjectedCost(probe.u.data());
        return probe;
      });
  std::vector<ProfileProbe> probes;
  for (auto& probe : all) {
    if (std::isfinite(probe.cost)) probes.push_back(std::move(probe));
  }
  return probes;
}

namespace {

// The covariance at u (cost ½χ² there) from a fresh Jacobian, with the noise scale of that cost,
// and (when asked) the fitted quantities it does not hold (Informative).
bool FreshCovariance(const FitModel& model, const std::vector<double>& u, double cost,
                     const FitOptions& options, Eigen::MatrixXd* covariance, double* noise_scale,
                     std::vector<int>* informative = nullptr,
                     Eigen::MatrixXd* jacobian_out = nullptr) {
  Eigen::VectorXd r;
  std::vector<Nuisance> nuisance;
  Eigen::MatrixXd jacobian;
  if (!model.ProjectedResiduals(u.data(), &r, &nuisance) ||
      !model.FullJacobian(u, nuisance, options.derivative_step, options.derivatives, &r,
                          &jacobian)) {
    return false;
  }
  const std::vector<int> fitted = model.FittedIndices();
  const double dof = std::max(1.0, static_cast<double>(model.residuals() - fitted.size()));
  *noise_scale = std::sqrt(2.0 * cost / dof);
  *covariance = Covariance(jacobian, fitted, *noise_scale);
  if (informative != nullptr) *informative = Informative(jacobian, fitted, *noise_scale);
  if (jacobian_out != nullptr) *jacobian_out = std::move(jacobian);
  return true;
}

}  // namespace

std::vector<std::vector<double>> HopPoints(const FitModel& model, const std::vector<double>& u,
                                           double cost, const FitOptions& options) {
  std::vector<std::vector<double>> points;
  Eigen::MatrixXd covariance;
  double noise_scale = 0.0;
  std::vector<int> informative;
  if (options.hops < 1 ||
      !FreshCovariance(model, u, cost, options, &covariance, &noise_scale, &informative)) {
    return points;
  }
  const int p = model.parameters();
  // The scene block of the covariance, factored: a hop of radius ρ is ρ standard errors of the
  // joint distribution in a random direction. A held parameter (Covariance) stays where it is: its
  // variance, the square of a standard error of up to 1e9 of its range, would also drown the
  // others' eigenvalues in the factorisation's roundoff.
  std::vector<int> moving;
  for (const int j : informative) {
    if (j < p) moving.push_back(j);
  }
  const int m = static_cast<int>(moving.size());
  Eigen::MatrixXd scene_block(m, m);
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b < m; ++b) scene_block(a, b) = covariance(moving[a], moving[b]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scene_block);
  const Eigen::VectorXd roots = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  const Eigen::MatrixXd root = eigen.eigenvectors() * roots.asDiagonal();
  std::mt19937_64 random(options.hop_seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int h = 0; h < options.hops; ++h) {
    // p draws whatever m is: the hops of a line without held parameters stay as they were.
    Eigen::VectorXd z(p);
    for (int i = 0; i < p; ++i) z(i) = uniform(random);
    const Eigen::VectorXd zm = z.head(m);
    if (!(zm.norm() > 0.0)) continue;
    const Eigen::VectorXd step = root * (options.hop_radius * zm / zm.norm());
    std::vector<double> point(u);
    for (int a = 0; a < m; ++a) {
      point[moving[a]] = std::clamp(u[moving[a]] + step(a), 0.0, 1.0);
    }
    points.push_back(std::move(point));
  }
  return points;
}

std::vector<std::vector<double>> GapKicks(const FitModel& model, const std::vector<double>& u,
                                          const FitOptions& options) {
  std::vector<std::vector<double>> points;
  if (!(options.gap_kick > 0.0)) return points;
  for (int i = 0; i < model.parameters(); ++i) {
    if (model.free(i).parameter.kind != driveline::SceneParameter::Kind::kBacklash) continue;
    const double gap = model.Physical(i, u[i]);
    for (int level = 0; level < options.gap_kick_levels; ++level) {
      for (const double sign : {1.0, -1.0}) {
        const double kicked = gap * (1.0 + sign * std::ldexp(options.gap_kick, level));
        if (kicked < model.free(i).lower || kicked > model.free(i).upper) continue;
        std::vector<double> point(u);
        point[i] = model.Unit(i, kicked);
        points.push_back(std::move(point));
      }
    }
  }
  return points;
}

namespace {

// The first point of a walk inward from a bound, as a fraction of the range (then doubled).
constexpr double kBoundWalkFirst = 1.0 / 16.0;

// Bisections of the open-gap edge (OpenGapEdge): the edge to 2⁻¹⁰ of where the gap sits.
constexpr int kEdgeBisections = 10;

// The smallest unit coordinate of slot `i`, between its lower bound and u[i], at which the cost
// (every other quantity held; gains and offsets solved) is still the cost at u[i]: below it the
// gap closes somewhere in the record. −1 when it closes nowhere above the lower bound.
double OpenGapEdge(const FitModel& model, const std::vector<double>& u, int i, double noise_scale) {
  std::vector<double> point(u);
  const auto cost_at = [&](double unit) {
    point[i] = unit;
    return model.ProjectedCost(point.data());
  };
  const double plateau = cost_at(u[i]);
  // χ² 1e-6 apart: the record has seen the gap close.
  const double touched = 0.5e-6 * noise_scale * noise_scale;
  const auto open = [&](double unit) {
    const double cost = cost_at(unit);
    return std::isfinite(cost) && std::abs(cost - plateau) <= touched;
  };
  if (!std::isfinite(plateau) || open(0.0)) return -1.0;
  double closed = 0.0;
  double still_open = u[i];
  for (int k = 0; k < kEdgeBisections; ++k) {
    const double middle = 0.5 * (closed + still_open);
    (open(middle) ? still_open : closed) = middle;
  }
  return still_open;
}

// u moved `distance` along `direction` (unit coordinates); empty when that leaves the unit box
// (past a bound the parameter cannot go, and that side says nothing about the spread inside).
// With `clamp_others_of` = i, only parameter i leaving it makes the point empty: another is held
// at the bound it would cross.
std::vector<double> AlongProfile(const std::vector<double>& u, const Eigen::VectorXd& direction,
                                 double distance, int clamp_others_of = -1) {
  std::vector<double> point(u);
  for (Eigen::Index s = 0; s < direction.size(); ++s) {
    point[s] += distance * direction(s);
    if (point[s] >= 0.0 && point[s] <= 1.0) continue;
    if (clamp_others_of < 0 || s == clamp_others_of || !std::isfinite(point[s])) return {};
    point[s] = std::clamp(point[s], 0.0, 1.0);
  }
  return point;
}

// One Gauss–Newton step of every fitted quantity but `held` from `point` (projected residuals
// `r` there), with the column-scaled Jacobian of the minimum; the step is cut back to the unit
// box. The straight profile direction is the linearisation's; along a curved valley the other
// quantities must move on, and this step finds how far.
class ProfileRelaxer {
 public:
  ProfileRelaxer(const Eigen::MatrixXd& jacobian, const std::vector<int>& fitted, int parameters)
      : fitted_(fitted),
        parameters_(parameters),
        norms_(fitted.size()),
        scaled_(jacobian.rows(), static_cast<Eigen::Index>(fitted.size())) {
    for (size_t j = 0; j < fitted.size(); ++j) {
      scaled_.col(j) = jacobian.col(fitted[j]);
      norms_(j) = scaled_.col(j).norm();
      if (norms_(j) > 0.0) scaled_.col(j) /= norms_(j);
    }
    normal_ = scaled_.transpose() * scaled_;
  }

  std::vector<double> Step(const std::vector<double>& point, const Eigen::VectorXd& r,
                           int held) const {
    std::vector<int> keep;
    for (size_t j = 0; j < fitted_.size(); ++j) {
      if (fitted_[j] != held && norms_(j) > 0.0) keep.push_back(static_cast<int>(j));
    }
    const Eigen::VectorXd gradient = scaled_.transpose() * r;
    const auto k = static_cast<Eigen::Index>(keep.size());
    Eigen::MatrixXd normal(k, k);
    Eigen::VectorXd rhs(k);
    for (Eigen::Index a = 0; a < k; ++a) {
      rhs(a) = -gradient(keep[a]);
      for (Eigen::Index b = 0; b < k; ++b) normal(a, b) = normal_(keep[a], keep[b]);
      normal(a, a) *= 1.0 + 1e-10;  // the columns are unit: a rank-deficient pair stays solvable
    }
    const Eigen::VectorXd step = normal.ldlt().solve(rhs);
    std::vector<double> relaxed(point);
    for (Eigen::Index a = 0; a < k; ++a) {
      const int slot = fitted_[keep[a]];
      if (slot >= parameters_ || !std::isfinite(step(a))) continue;
      relaxed[slot] = std::clamp(point[slot] + step(a) / norms_(keep[a]), 0.0, 1.0);
    }
    return relaxed;
  }

 private:
  const std::vector<int>& fitted_;
  int parameters_;
  Eigen::VectorXd norms_;
  Eigen::MatrixXd scaled_;
  Eigen::MatrixXd normal_;
};

// A point held at χ² above the best minimum's cost moved parameter j by d_j: in the quadratic
// picture the linearisation draws, no point at χ² lies further than √χ² standard errors in any
// parameter, so one within profile_chi2 widens j's error to d_j / √max(χ², 1) (`widening`, per
// scene slot; a slot already ∞, a lower cost found, is left so).
void WidenByHeldPoints(const FitModel& model, const std::vector<double>& u,
                       const Eigen::MatrixXd& covariance, double best_cost, double chi2_per_cost,
                       double profile_chi2,
                       std::initializer_list<const std::vector<ProfileProbe>*> held,
                       std::vector<double>* widening) {
  for (int j = 0; j < model.parameters(); ++j) {
    const double variance = covariance(j, j);
    if (!(variance > 0.0) || !std::isfinite(variance) || !std::isfinite((*widening)[j])) continue;
    const double standard_error = std::sqrt(variance) * model.slot(j).map.PhysicalPerUnit(u[j]);
    const double estimate = model.Physical(j, u[j]);
    for (const std::vector<ProfileProbe>* points : held) {
      for (const ProfileProbe& point : *points) {
        const double chi2 = (point.cost - best_cost) * chi2_per_cost;
        if (!(chi2 < profile_chi2)) continue;
        const double distance = std::abs(model.Physical(j, point.u[j]) - estimate);
        (*widening)[j] =
            std::max((*widening)[j], distance / std::sqrt(std::max(chi2, 1.0)) / standard_error);
      }
    }
  }
}

}  // namespace

std::vector<std::vector<double>> CurvedValleyPoints(const FitModel& model,
                                                    const std::vector<double>& u, double cost,
                                                    const FitOptions& options,
                                                    std::vector<ProfileProbe>* bound_walks,
                                                    std::vector<ProfileProbe>* gap_points) {
  std::vector<std::vector<double>> lower;
  Eigen::MatrixXd covariance;
  double noise_scale = 0.0;
  Eigen::MatrixXd jacobian;
  if (!(options.curved_valley_ratio > 0.0) ||
      !FreshCovariance(model, u, cost, options, &covariance, &noise_scale, nullptr, &jacobian)) {
    return lower;
  }
  const int p = model.parameters();
  const double step = options.profile_step;
  const double predicted = 0.5 * step * step * noise_scale * noise_scale;
  struct Held {
    int slot;
    std::vector<double> start;
    int iterations;
  };
  std::vector<Held> held;
  for (int i = 0; i < p; ++i) {
    const double variance = covariance(i, i);
    if (!(variance > 0.0) || !std::isfinite(variance)) continue;
    const Eigen::VectorXd direction = covariance.col(i).head(p) / std::sqrt(variance);
    // Another parameter the direction moves past a bound is held there (random line 7832 with a
    // fitted stiffness: dropped, those probes left the truth's valley unfollowed).
    const auto along = [&](double distance) { return AlongProfile(u, direction, distance, i); };
    double steepest = 0.0;
    for (const double sign : {-1.0, 1.0}) {
      const std::vector<double> probe = along(sign * step);
      if (!probe.empty()) {
        const double rise = model.ProjectedCost(probe.data()) - cost;
        if (std::isfinite(rise)) steepest = std::max(steepest, rise);
      }
    }
    if (!(steepest > options.curved_valley_ratio * predicted)) continue;
    // The misfit is far from quadratic two standard errors away: the valley bends sharply, and
    // the linearisation says nothing of what lies further along it.
    for (const double sign : {-1.0, 1.0}) {
      for (double distance = 2.0 * step; distance <= options.profile_relax_reach * (1.0 + 1e-9);
           distance *= 2.0) {
        std::vector<double> start = along(sign * distance);
        if (start.empty()) break;
        held.push_back({i, std::move(start), options.curved_valley_iterations});
      }
    }
  }
  // A gap the record hardly depends on (EstimateUncertainty's test: alone, its standard error
  // would exceed unidentifiable_fraction of its range) may never close at the minimum, while
  // the other quantities make up for it. Where it would close, the linearisation does not say:
  // it is held just below the edge of the open gaps' plateau (OpenGapEdge), then further down.
  for (int i = 0; i < p && i < jacobian.cols() && options.open_gap_points > 0; ++i) {
    if (model.free(i).parameter.kind != driveline::SceneParameter::Kind::kBacklash) continue;
    if (AloneStandardError(jacobian.col(i).norm(), noise_scale) <=
        options.unidentifiable_fraction) {
      continue;
    }
    const double edge = OpenGapEdge(model, u, i, noise_scale);
    if (!(edge > 0.0)) continue;
    for (int k = options.open_gap_points; k >= 1; --k) {
      std::vector<double> start(u);
      start[i] = edge * (1.0 - std::ldexp(1.0, -k));
      held.push_back({i, std::move(start), options.curved_valley_iterations});
    }
  }
  // A parameter at a bound: the minimum is the bound's, not the misfit's, and its linearisation
  // says nothing of the inside. Its profile is followed inward, held at 1/16 … 1/2 of its range.
  // So is one within bound_walk_se standard errors of a bound: its interval reaches past the
  // bound, whose side the profile check cannot probe, and Levenberg–Marquardt, slow where u
  // flattens against a bound, may have stopped short of it (random line 9661 with a fast
  // recorder low-pass: a damping 1.4e-5 of its range above its lower bound, its error 0.2 of the
  // range; the truth's valley at half the range, χ² 21 lower, behind a wall the followed
  // profile's first point never left).
  const size_t curved_walks = held.size();
  for (int i = 0; i < p; ++i) {
    const double variance = covariance(i, i);
    const double near = variance > 0.0 && std::isfinite(variance)
                            ? std::max(kAtBound, options.bound_walk_se * std::sqrt(variance))
                            : kAtBound;
    const bool low = u[i] <= near;
    if (!low && u[i] < 1.0 - near) continue;
    for (double reach = kBoundWalkFirst; reach <= 0.5; reach *= 2.0) {
      std::vector<double> start(u);
      start[i] = low ? reach : 1.0 - reach;
      held.push_back({i, std::move(start), options.curved_valley_iterations});
    }
  }
  // A gap's profile can have a second valley behind a wall that no probe near the minimum
  // crosses (random line 9326 under a drive loop: the upper spindle's gap at 2.3 mrad, χ² 17 at
  // 5 mrad, 5 at the truth's 7). Each fitted gap is held across its range, the others refitted.
  const size_t gap_walks = held.size();
  for (int i = 0; i < p && options.gap_profile_points > 0; ++i) {
    if (model.free(i).parameter.kind != driveline::SceneParameter::Kind::kBacklash) continue;
    const double spread = step * std::sqrt(std::max(covariance(i, i), 0.0));
    for (int k = 0; k < options.gap_profile_points; ++k) {
      const double at = (k + 0.5) / options.gap_profile_points;
      if (std::abs(at - u[i]) <= spread) continue;  // the profile check's own probes are there
      std::vector<double> start(u);
      start[i] = at;
      held.push_back({i, std::move(start), options.profile_iterations});
    }
  }
  const std::vector<LocalFit> walked = MapOverCopies<LocalFit>(
      model, options.threads, static_cast<int>(held.size()), [&](const FitModel& copy, int k) {
        return Refine(copy, options, held[k].start, false, held[k].iterations, {held[k].slot});
      });
  for (size_t k = curved_walks; k < held.size(); ++k) {
    if (!walked[k].usable) continue;
    (k < gap_walks ? bound_walks : gap_points)
        ->push_back({held[k].slot, walked[k].u, walked[k].cost});
  }
  // χ² more than 1 below the minimum's: another valley, not the misfit's roughness.
  const double below = cost - 0.5 * noise_scale * noise_scale;
  std::vector<const LocalFit*> found;
  for (const auto& fit : walked) {
    if (fit.usable && fit.cost < below) found.push_back(&fit);
  }
  std::stable_sort(found.begin(), found.end(),
                   [](const LocalFit* a, const LocalFit* b) { return a->cost < b->cost; });
  for (const LocalFit* fit : found) lower.push_back(fit->u);
  return lower;
}

std::vector<double> ProfileWidening(const FitModel& model, const std::vector<double>& u,
                                    const Eigen::MatrixXd& jacobian, const std::vector<int>& fitted,
                                    const Eigen::MatrixXd& covariance, double best_cost,
                                    double noise_scale, const FitOptions& options,
                                    const std::vector<ProfileProbe>& probes,
                                    const std::vector<ProfileProbe>& bound_walks,
                                    std::optional<ProfileProbe>* lower, int* relaxed_walks) {
  const int p = model.parameters();
  std::vector<double> widening(p, 1.0);
  lower->reset();
  const auto found_lower = [lower](int slot, const std::vector<double>& point, double cost) {
    if (!lower->has_value() || cost < (*lower)->cost) *lower = ProfileProbe{slot, point, cost};
  };
  if (relaxed_walks != nullptr) *relaxed_walks = 0;
  const double step = options.profile_step;
  const double predicted = 0.5 * step * step * noise_scale * noise_scale;
  const double chi2_per_cost = 2.0 / (noise_scale * noise_scale);
  const double floor_cost = FloorCost(options);  // lower by no more: the minimum's own floor
  const bool relax = options.profile_relax_widening > 0.0;
  const ProfileRelaxer relaxer(jacobian, fitted, p);
  std::vector<ProfileProbe> followed;  // the points held on followed profiles
  for (int i = 0; i < p; ++i) {
    const double variance = covariance(i, i);
    if (!(variance > 0.0) || !std::isfinite(variance)) continue;
    const Eigen::VectorXd direction = covariance.col(i).head(p) / std::sqrt(variance);
    // The axis probes and the followed profile, in physical units (a log-scaled parameter's
    // spread is not symmetric in u): a point held at distance d with a profile χ² implies a
    // standard error of d / √max(χ², 1) (a parabola through it; below χ² 1 the misfit's
    // roughness decides, and the point is at least within one standard error).
    const double per_unit = model.slot(i).map.PhysicalPerUnit(u[i]);
    const double standard_error = std::sqrt(variance) * per_unit;
    const double estimate = model.Physical(i, u[i]);
    const auto implied = [&](double value, double chi2) {
      return std::abs(model.Physical(i, value) - estimate) / std::sqrt(std::max(chi2, 1.0)) /
             standard_error;
    };
    const auto along = [&](double sign, double distance) {
      // Another parameter that the direction would take out of its bounds is held at the bound
      // (a parameter not identifiable, with a huge variance, otherwise takes every probe of the
      // parameters correlated with it out of the box, and they go unchecked: random line 7872).
      return AlongProfile(u, direction, sign * distance, i);
    };
    double flattest = std::numeric_limits<double>::infinity();
    for (const double sign : {-1.0, 1.0}) {
      const std::vector<double> probe = along(sign, step);
      Eigen::VectorXd r;
      if (probe.empty() || !model.ProjectedResiduals(probe.data(), &r)) continue;
      const double rise = 0.5 * r.squaredNorm() - best_cost;
      flattest = std::min(flattest, rise);
      if (rise < -floor_cost) found_lower(i, probe, best_cost + rise);
      if (!relax || !(rise >= 0.0)) continue;
      // The probe relaxed by one Gauss–Newton step of the others: whether it implies a standard
      // error more than profile_relax_widening times the linearised one.
      const auto relaxed_wider = [&](const std::vector<double>& at, const Eigen::VectorXd& r_at) {
        const std::vector<double> relaxed = relaxer.Step(at, r_at, i);
        const double relaxed_chi2 =
            (model.ProjectedCost(relaxed.data()) - best_cost) * chi2_per_cost;
        return implied(at[i], relaxed_chi2) > options.profile_relax_widening;
      };
      // Where the straight probe rises far above the prediction, the valley bends sharply and the
      // step with the minimum's Jacobian says little: that side is followed in any case.
      const bool bends =
          options.profile_bend_ratio > 0.0 && rise > options.profile_bend_ratio * predicted;
      if (!bends && !relaxed_wider(probe, r)) {
        // A profile can be quadratic out to the step and flatten beyond it (a shoulder: under
        // no_pull, random line 8831's gap rose χ² 3.3 at 2 standard errors, as predicted, and
        // 6.7 at 5.6 where the truth lay). The relaxed probe at twice the step as well.
        const std::vector<double> further = along(sign, 2.0 * step);
        Eigen::VectorXd r_further;
        if (further.empty() || !model.ProjectedResiduals(further.data(), &r_further)) continue;
        const double further_rise = 0.5 * r_further.squaredNorm() - best_cost;
        if (further_rise < -floor_cost) found_lower(i, further, best_cost + further_rise);
        if (!(further_rise >= 0.0) || !relaxed_wider(further, r_further)) continue;
      }
      // The valley curves away from the straight line: follow this side of the profile.
      if (relaxed_walks != nullptr) ++*relaxed_walks;
      for (double distance = step; distance <= options.profile_relax_reach * (1.0 + 1e-9);
           distance *= 2.0) {
        const std::vector<double> start = along(sign, distance);
        if (start.empty()) break;
        const LocalFit held = Refine(model, options, start, false, options.profile_iterations, {i});
        if (!held.usable) break;
        const double chi2 = (held.cost - best_cost) * chi2_per_cost;
        if (chi2 < -1.0) found_lower(i, held.u, held.cost);
        if (!(chi2 < options.profile_chi2)) break;
        widening[i] = std::max(widening[i], implied(start[i], chi2));
        followed.push_back({i, held.u, held.cost});
      }
    }
    if (flattest < 0.0) {
      widening[i] = std::numeric_limits<double>::infinity();
      continue;
    }
    if (std::isfinite(flattest) && flattest < predicted) {
      widening[i] =
          std::max(widening[i], std::sqrt(predicted / std::max(flattest, 1e-12 * predicted)));
    }
    for (const auto& probe : probes) {
      if (probe.slot != i) continue;
      const double chi2 = (probe.cost - best_cost) * chi2_per_cost;
      if (chi2 < 0.0) {
        if (probe.cost < best_cost - floor_cost) found_lower(i, probe.u, probe.cost);
        continue;
      }
      if (!(chi2 < options.profile_chi2)) continue;
      const double implied_axis =
          std::abs(model.Physical(i, probe.u[i]) - estimate) / std::sqrt(std::max(chi2, 1e-12));
      widening[i] = std::max(widening[i], implied_axis / standard_error);
    }
  }
  // A point held on a followed profile or on a walk inward from a bound moved the other
  // parameters too.
  WidenByHeldPoints(model, u, covariance, best_cost, chi2_per_cost, options.profile_chi2,
                    {&followed, &bound_walks}, &widening);
  return widening;
}

std::vector<double> GapRangeWidening(const FitModel& model, const std::vector<double>& u,
                                     const Eigen::MatrixXd& covariance, double best_cost,
                                     double noise_scale, const FitOptions& options,
                                     const std::vector<ProfileProbe>& gap_points) {
  std::vector<double> widening(model.parameters(), 1.0);
  WidenByHeldPoints(model, u, covariance, best_cost, 2.0 / (noise_scale * noise_scale),
                    options.profile_chi2, {&gap_points}, &widening);
  return widening;
}

void WidenAlongProfiles(const std::vector<double>& widening, Eigen::MatrixXd* covariance,
                        const std::vector<double>& alone) {
  const Eigen::MatrixXd given = *covariance;
  for (size_t i = 0; i < widening.size(); ++i) {
    const auto s = static_cast<Eigen::Index>(i);
    if (widening[i] > 1.0 && std::isfinite(widening[i]) && given(s, s) > 0.0) {
      *covariance +=
          (widening[i] * widening[i] - 1.0) / given(s, s) * given.col(s) * given.col(s).transpose();
    }
  }
  for (size_t i = 0; i < alone.size(); ++i) {
    const auto s = static_cast<Eigen::Index>(i);
    const double wanted = alone[i] * alone[i] * given(s, s);
    if (!(alone[i] > 1.0) || !std::isfinite(alone[i]) || !(wanted > (*covariance)(s, s))) {
      continue;
    }
    const double factor = std::sqrt(wanted / (*covariance)(s, s));
    covariance->row(s) *= factor;
    covariance->col(s) *= factor;
  }
}

void FlagPlateaus(const FitModel& model, const std::vector<ProfileProbe>& probes,
                  const std::vector<double>& standard_errors, FitResult* result) {
  for (int i = 0; i < model.parameters(); ++i) {
    auto& estimate = result->parameters[i];
    if (!estimate.identifiable) continue;
    std::vector<const ProfileProbe*> axis;
    for (const auto& probe : probes) {
      if (probe.slot == i) axis.push_back(&probe);
    }
    // Neighbouring probes with the same cost to 1e-10: the simulated record does not change
    // between them.
    double low = std::numeric_limits<double>::infinity();
    double high = -low;
    for (size_t k = 1; k < axis.size(); ++k) {
      const double a = axis[k - 1]->cost;
      const double b = axis[k]->cost;
      if (std::abs(a - b) <= 1e-10 * std::abs(a)) {
        low = std::min(low, model.Physical(i, axis[k - 1]->u[i]));
        high = std::max(high, model.Physical(i, axis[k]->u[i]));
      }
    }
    if (!(low < high)) continue;
    const double se = standard_errors[i];
    const double distance =
        std::min(std::abs(low - estimate.value), std::abs(high - estimate.value));
    if (estimate.value >= low && estimate.value <= high) {
      estimate.identifiable = false;
      estimate.why_not = "the record is the same for every value in [" + ShortNumber(low) + ", " +
                         ShortNumber(high) + "] " + estimate.unit;
    } else if (!(distance <= 3.0 * se)) {
      estimate.identifiable = false;
      estimate.why_not = "the record is the same for every value in [" + ShortNumber(low) + ", " +
                         ShortNumber(high) + "] " + estimate.unit + " (a plateau of the cost " +
                         ShortNumber(distance / se) +
                         " standard errors away): the record bounds it " + "from one side only";
    }
  }
}

}  // namespace millkit::identify
