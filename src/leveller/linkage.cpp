#include "millkit/leveller/linkage.h"

#include <ceres/jet.h>

#include <algorithm>
#include <numbers>

#include "io/invariant.h"
#include "millkit/io/input_error.h"

namespace millkit::leveller {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;
// A closed-form angle this close outside the working range is clamped onto it; the forward re-check
// then decides (near a dead centre, roundoff of 1e-13 mm in Y moves β by up to ~1e-9 deg).
constexpr double kRangeEdgeToleranceDeg = 1e-6;
// Circle pairs this close to tangency (h² ≥ −k r²) meet at one point: the dead centres, where
// roundoff makes h² slightly negative. The forward re-check decides.
constexpr double kTangencyRelativeTolerance = 1e-10;

double Cross(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

// The intersection of circle(p0, r0) and circle(p1, r1) on the side `branch` (+1 or −1) of the line
// p0 → p1: cross(p1 − p0, out − p0) has the sign of `branch`.
bool BranchIntersection(const Vec2<double>& p0, double r0, const Vec2<double>& p1, double r1,
                        double branch, Vec2<double>* out) {
  const double dx = p1.x - p0.x;
  const double dy = p1.y - p0.y;
  const double d2 = dx * dx + dy * dy;
  if (!(d2 > 0.0)) return false;
  const double d = std::sqrt(d2);
  const double a = (r0 * r0 - r1 * r1 + d2) / (2.0 * d);
  const double h2 = r0 * r0 - a * a;
  if (h2 < -kTangencyRelativeTolerance * r0 * r0) return false;
  const double h = std::sqrt(std::max(h2, 0.0));
  const double ux = dx / d;
  const double uy = dy / d;
  out->x = p0.x + a * ux - branch * h * uy;
  out->y = p0.y + a * uy + branch * h * ux;
  return true;
}

double WrapDeg(double angle_deg) {
  while (angle_deg > 180.0) angle_deg -= 360.0;
  while (angle_deg <= -180.0) angle_deg += 360.0;
  return angle_deg;
}

std::array<double, 2> DeadCentres(const Vec2<double>& pivot, const Vec2<double>& pin) {
  const double toward = std::atan2(pin.y - pivot.y, pin.x - pivot.x) * kDegPerRad;
  std::array<double, 2> angles{WrapDeg(toward), WrapDeg(toward + 180.0)};
  std::sort(angles.begin(), angles.end());
  return angles;
}

}  // namespace

std::string ToString(InverseStatus status) {
  switch (status) {
    case InverseStatus::kOk:
      return "ok";
    case InverseStatus::kBeamTiltImpossible:
      return "beam tilt impossible (|y_F - y_E| > EF)";
    case InverseStatus::kGuideCannotReach:
      return "guide CG cannot reach the beam pin G";
    case InverseStatus::kRodGjCannotReach:
      return "rod GJ cannot reach the eccentric circle of J";
    case InverseStatus::kRodHkCannotReach:
      return "rod HK cannot reach the eccentric circle of K";
    case InverseStatus::kAngleOutsideRange:
      return "eccentric angle outside the working range";
    case InverseStatus::kLengthOutsideRange:
      return "cylinder length outside its range";
    case InverseStatus::kAssemblyMismatch:
      return "the forward assembly of the answer misses the target";
  }
  return "unknown";
}

Linkage::Linkage(const LinkageGeometry& geometry, UncheckedTag) : geometry_(geometry) {
  const auto& geo = geometry_;
  gh_mm_ = std::hypot(geo.h0.x - geo.g0.x, geo.h0.y - geo.g0.y);
  ef_mm_ = std::hypot(geo.f0.x - geo.e0.x, geo.f0.y - geo.e0.y);
  // Branches of the reference pose β = (0, 0) (or the middle of the working range).
  const double mid = 0.5 * (geo.beta_min_deg + geo.beta_max_deg);
  Intermesh<double> y;
  LinkagePose<double> pose;
  if (Forward(mid, mid, &y, &pose)) {
    guide_side_ = pose.g.x >= geo.c.x ? 1.0 : -1.0;
    branch_j_ =
        Cross(pose.g.x - geo.b.x, pose.g.y - geo.b.y, pose.j.x - geo.b.x, pose.j.y - geo.b.y) >= 0.0
            ? 1.0
            : -1.0;
    branch_k_ =
        Cross(pose.h.x - geo.a.x, pose.h.y - geo.a.y, pose.k.x - geo.a.x, pose.k.y - geo.a.y) >= 0.0
            ? 1.0
            : -1.0;
  }
}

Linkage Linkage::Unchecked(const LinkageGeometry& geometry) {
  return Linkage(geometry, UncheckedTag{});
}

Linkage::Linkage(const LinkageGeometry& geometry) : Linkage(geometry, UncheckedTag{}) {
  ValidateLinkage(geometry, "linkage geometry [linkage]");
}

bool Linkage::BeamFromIntermesh(double y1_mm, double y2_mm, LinkagePose<double>* pose,
                                InverseStatus* status) const {
  const auto& geo = geometry_;
  const double top = geo.lower_y_mm + geo.roll_diameter_mm;
  const double ye = top - y1_mm;
  const double yf = top - y2_mm;
  // Seed §3 1): tilt of EF, sin θ = (y_F − y_E) / L8.
  const double s = (yf - ye) / ef_mm_;
  if (std::abs(s) > 1.0) {
    *status = InverseStatus::kBeamTiltImpossible;
    return false;
  }
  const double theta0 = std::atan2(geo.f0.y - geo.e0.y, geo.f0.x - geo.e0.x);
  const double asn = std::asin(s);
  auto wrap = [](double a) { return std::remainder(a, 2.0 * std::numbers::pi); };
  const double phi1 = wrap(asn - theta0);
  const double phi2 = wrap(std::numbers::pi - asn - theta0);
  const double phi = std::abs(phi1) <= std::abs(phi2) ? phi1 : phi2;
  const double c = std::cos(phi);
  const double sn = std::sin(phi);
  auto rotate = [&](const Point2& p) {
    const double rx = p.x - geo.e0.x;
    const double ry = p.y - geo.e0.y;
    return Vec2<double>{c * rx - sn * ry, sn * rx + c * ry};
  };
  const auto g_rel = rotate(geo.g0);
  const auto h_rel = rotate(geo.h0);
  const auto f_rel = rotate(geo.f0);
  const double gy = ye + g_rel.y;
  const double disc = geo.cg_mm * geo.cg_mm - (gy - geo.c.y) * (gy - geo.c.y);
  if (disc < 0.0) {
    *status = InverseStatus::kGuideCannotReach;
    return false;
  }
  const double gx = geo.c.x + guide_side_ * std::sqrt(disc);
  const double ex = gx - g_rel.x;
  pose->e = {ex, ye};
  pose->f = {ex + f_rel.x, ye + f_rel.y};
  pose->g = {gx, gy};
  pose->h = {ex + h_rel.x, ye + h_rel.y};
  *status = InverseStatus::kOk;
  return true;
}

AngleSetpoint Linkage::InverseClosedForm(double y1_mm, double y2_mm, double tolerance_mm) const {
  const auto& geo = geometry_;
  AngleSetpoint out;
  LinkagePose<double> pose;
  if (!BeamFromIntermesh(y1_mm, y2_mm, &pose, &out.status)) return out;
  const Vec2<double> a{geo.a.x, geo.a.y};
  const Vec2<double> b{geo.b.x, geo.b.y};
  if (!BranchIntersection(b, geo.bj_mm, pose.g, geo.gj_mm, branch_j_, &pose.j)) {
    out.status = InverseStatus::kRodGjCannotReach;
    return out;
  }
  if (!BranchIntersection(a, geo.ak_mm, pose.h, geo.hk_mm, branch_k_, &pose.k)) {
    out.status = InverseStatus::kRodHkCannotReach;
    return out;
  }
  out.beta1_deg = std::atan2(pose.k.y - a.y, pose.k.x - a.x) * kDegPerRad;
  out.beta2_deg = std::atan2(pose.j.y - b.y, pose.j.x - b.x) * kDegPerRad;
  bool clamped = false;
  for (double* beta : {&out.beta1_deg, &out.beta2_deg}) {
    if (*beta < geo.beta_min_deg - kRangeEdgeToleranceDeg ||
        *beta > geo.beta_max_deg + kRangeEdgeToleranceDeg) {
      out.status = InverseStatus::kAngleOutsideRange;
      return out;
    }
    const double inside = std::clamp(*beta, geo.beta_min_deg, geo.beta_max_deg);
    clamped = clamped || inside != *beta;
    *beta = inside;
  }
  Intermesh<double> y;
  if (!Forward(out.beta1_deg, out.beta2_deg, &y)) {
    out.status = InverseStatus::kAssemblyMismatch;
    return out;
  }
  out.y3_mm = y.y3;
  out.residual_mm = std::max(std::abs(y.y1 - y1_mm), std::abs(y.y2 - y2_mm));
  if (!(out.residual_mm <= tolerance_mm)) {
    out.status = clamped ? InverseStatus::kAngleOutsideRange : InverseStatus::kAssemblyMismatch;
  }
  return out;
}

LengthSetpoint Linkage::InverseLengths(double y1_mm, double y2_mm, const HydraulicRange& range,
                                       double tolerance_mm) const {
  const auto& geo = geometry_;
  LengthSetpoint out;
  LinkagePose<double> pose;
  if (!BeamFromIntermesh(y1_mm, y2_mm, &pose, &out.status)) return out;
  out.ah_mm = std::hypot(pose.h.x - geo.a.x, pose.h.y - geo.a.y);
  out.bg_mm = std::hypot(pose.g.x - geo.b.x, pose.g.y - geo.b.y);
  if (out.ah_mm < range.ah_min_mm || out.ah_mm > range.ah_max_mm || out.bg_mm < range.bg_min_mm ||
      out.bg_mm > range.bg_max_mm) {
    out.status = InverseStatus::kLengthOutsideRange;
    return out;
  }
  Intermesh<double> y;
  if (!ForwardLengths(out.ah_mm, out.bg_mm, &y)) {
    out.status = InverseStatus::kAssemblyMismatch;
    return out;
  }
  out.y3_mm = y.y3;
  out.residual_mm = std::max(std::abs(y.y1 - y1_mm), std::abs(y.y2 - y2_mm));
  if (!(out.residual_mm <= tolerance_mm)) out.status = InverseStatus::kAssemblyMismatch;
  return out;
}

Eigen::Matrix<double, 3, 2> Linkage::Jacobian(double beta1_deg, double beta2_deg) const {
  using Jet = ceres::Jet<double, 2>;
  const Jet b1(beta1_deg, 0);
  const Jet b2(beta2_deg, 1);
  Intermesh<Jet> y;
  const bool assembled = Forward(b1, b2, &y);
  MILLKIT_CHECK(assembled, "Jacobian: the linkage does not assemble at this pose");
  (void)assembled;
  Eigen::Matrix<double, 3, 2> jacobian;
  jacobian.row(0) = y.y1.v.transpose();
  jacobian.row(1) = y.y2.v.transpose();
  jacobian.row(2) = y.y3.v.transpose();
  return jacobian;
}

std::array<double, 2> Linkage::DeadCentresBeta1(double beta1_deg, double beta2_deg) const {
  Intermesh<double> y;
  LinkagePose<double> pose;
  if (!Forward(beta1_deg, beta2_deg, &y, &pose))
    return {geometry_.beta_min_deg, geometry_.beta_max_deg};
  return DeadCentres({geometry_.a.x, geometry_.a.y}, pose.h);
}

std::array<double, 2> Linkage::DeadCentresBeta2(double beta1_deg, double beta2_deg) const {
  Intermesh<double> y;
  LinkagePose<double> pose;
  if (!Forward(beta1_deg, beta2_deg, &y, &pose))
    return {geometry_.beta_min_deg, geometry_.beta_max_deg};
  return DeadCentres({geometry_.b.x, geometry_.b.y}, pose.g);
}

SetpointAccuracy Linkage::Accuracy(double beta1_deg, double beta2_deg, double encoder_deg) const {
  SetpointAccuracy out;
  const auto jacobian = Jacobian(beta1_deg, beta2_deg);
  for (int k = 0; k < 3; ++k) {
    out.delta_y_mm[k] = (std::abs(jacobian(k, 0)) + std::abs(jacobian(k, 1))) * encoder_deg;
    out.max_delta_y_mm = std::max(out.max_delta_y_mm, out.delta_y_mm[k]);
  }
  double distance = 360.0;
  for (double dead : DeadCentresBeta1(beta1_deg, beta2_deg)) {
    distance = std::min(distance, std::abs(WrapDeg(beta1_deg - dead)));
  }
  for (double dead : DeadCentresBeta2(beta1_deg, beta2_deg)) {
    distance = std::min(distance, std::abs(WrapDeg(beta2_deg - dead)));
  }
  out.dead_centre_distance_deg = distance;
  return out;
}

}  // namespace millkit::leveller
