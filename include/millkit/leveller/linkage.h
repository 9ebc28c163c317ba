// Linkage kinematics of the seven-roll leveller (SPEC.md §6.2, seed 004 fig. 2 and 4).
//
// Forward, eccentric drive: β1 (angle of K about A), β2 (angle of J about B), degrees CCW from +x,
//   K = A + L7 (cos β1, sin β1),  J = B + L1 (cos β2, sin β2)
//   G = lower (smaller y) intersection of circle(C, L3) and circle(J, L2)
//   H = lower intersection of circle(G, |GH|) and circle(K, L6)
//   the beam (E, F, G, H rigid, shape from the zero pose) follows from G and H;
//   Y1 = Yd + D − y_E,  Y2 = Yd + D − y_F,  Y3 = 2 Y2 − Y1  (roll 3# at 2F − E; seed: Y3 = 2Y2 −
//   Y1).
// Forward, hydraulic variant (seed fig. 5-6): |BG| and |AH| are inputs; G = lower intersection of
//   circle(C, L3) and circle(B, |BG|), H = lower intersection of circle(G, |GH|) and circle(A,
//   |AH|).
// Closed-form inverse (seed §3 1)): from Y1, Y2 the beam tilt sin θ = (y_F − y_E)/L8, the guide
//   |CG| = L3 fixes the beam's x position (branch of the reference pose β = (0, 0)), then J and K
//   are circle intersections on the principal branch: the side of line BG (AH) on which J (K) lies
//   at β = 0. The principal branch spans the angles between the two dead centres (J on line BG);
//   the working range is [beta_min, beta_max] ∩ principal branch. In the default geometry the dead
//   centre near −90° lies at about −89.98°, so a 0.02° sliver of [−90°, −89.98°] is beyond the dead
//   centre: its intermesh values are reached again on the principal branch, and the inverse returns
//   those.
// Accuracy (SPEC.md §6.2): ΔY_k = Σ_j |∂Y_k/∂β_j| Δβ for an encoder resolution Δβ; ∂Y/∂β → 0 at the
//   dead centres, where small ΔY hides a large angle uncertainty.
// Units: mm and degrees. Nothing here throws except the constructor on a degenerate geometry.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "millkit/leveller/leveller_config.h"

namespace millkit::leveller {

template <typename T>
struct Vec2 {
  T x;
  T y;
};

template <typename T>
struct LinkagePose {
  Vec2<T> e, f, g, h, j, k;
};

// Intermesh (plunge, positive down into the strip) of upper rolls 1#, 2#, 3#, mm.
template <typename T>
struct Intermesh {
  T y1;
  T y2;
  T y3;
};

enum class InverseStatus {
  kOk,
  kBeamTiltImpossible,  // |y_F − y_E| > L8
  kGuideCannotReach,    // no x puts G on circle(C, L3)
  kRodGjCannotReach,    // circle(B, L1) and circle(G, L2) do not meet
  kRodHkCannotReach,    // circle(A, L7) and circle(H, L6) do not meet
  kAngleOutsideRange,   // principal-branch angle outside [beta_min, beta_max]
  kLengthOutsideRange,  // hydraulic: |AH| or |BG| outside the cylinder range
  kAssemblyMismatch,    // forward assembly of the answer does not return the target
};
std::string ToString(InverseStatus status);

struct AngleSetpoint {
  InverseStatus status = InverseStatus::kOk;
  double beta1_deg = 0.0;
  double beta2_deg = 0.0;
  double y3_mm = 0.0;
  double residual_mm = 0.0;  // max |Y(β) − target| of the re-check through the forward map
  bool ok() const { return status == InverseStatus::kOk; }
};

struct LengthSetpoint {
  InverseStatus status = InverseStatus::kOk;
  double ah_mm = 0.0;
  double bg_mm = 0.0;
  double y3_mm = 0.0;
  double residual_mm = 0.0;
  bool ok() const { return status == InverseStatus::kOk; }
};

// ΔY of the three upper rolls for one encoder resolution, and how close the pose is to a dead
// centre (angle between β and the nearest dead-centre angle of that eccentric, degrees).
struct SetpointAccuracy {
  std::array<double, 3> delta_y_mm{};  // worst case Σ_j |∂Y_k/∂β_j| Δβ
  double max_delta_y_mm = 0.0;
  double dead_centre_distance_deg = 0.0;
};

class Linkage {
 public:
  // Throws InputError (naming the key) when FindLinkageDefect finds a defect.
  explicit Linkage(const LinkageGeometry& geometry);
  // Without the defect check (used by FindLinkageDefect itself).
  static Linkage Unchecked(const LinkageGeometry& geometry);

  const LinkageGeometry& geometry() const { return geometry_; }

  // Eccentric forward map; false when a circle pair does not meet (no assembly).
  template <typename T>
  bool Forward(const T& beta1_deg, const T& beta2_deg, Intermesh<T>* y,
               LinkagePose<T>* pose = nullptr) const;

  // Hydraulic forward map from the cylinder lengths |AH|, |BG| (mm).
  template <typename T>
  bool ForwardLengths(const T& ah_mm, const T& bg_mm, Intermesh<T>* y,
                      LinkagePose<T>* pose = nullptr) const;

  // Closed-form inverse on the principal branch, re-checked through Forward (tolerance
  // `tolerance_mm` on the residual, default 1e-9 mm).
  AngleSetpoint InverseClosedForm(double y1_mm, double y2_mm, double tolerance_mm = 1e-9) const;
  // Hydraulic inverse: the cylinder lengths for (Y1, Y2), range-checked.
  LengthSetpoint InverseLengths(double y1_mm, double y2_mm, const HydraulicRange& range,
                                double tolerance_mm = 1e-9) const;

  // ∂(Y1, Y2, Y3)/∂(β1, β2) in mm per degree (automatic differentiation of Forward).
  // Precondition: Forward succeeds at β.
  Eigen::Matrix<double, 3, 2> Jacobian(double beta1_deg, double beta2_deg) const;

  SetpointAccuracy Accuracy(double beta1_deg, double beta2_deg, double encoder_deg) const;

  // Angles (degrees) at which K (or J) is on line AH (BG) at the pose of β: the dead centres of
  // each eccentric, below (first) and above (second) the principal branch.
  std::array<double, 2> DeadCentresBeta1(double beta1_deg, double beta2_deg) const;
  std::array<double, 2> DeadCentresBeta2(double beta1_deg, double beta2_deg) const;

 private:
  // Beam pose from the intermesh pair (closed form); false with a status on failure.
  bool BeamFromIntermesh(double y1_mm, double y2_mm, LinkagePose<double>* pose,
                         InverseStatus* status) const;

  struct UncheckedTag {};
  Linkage(const LinkageGeometry& geometry, UncheckedTag);

  template <typename T>
  bool BeamFromPins(const Vec2<T>& g, const Vec2<T>& h, LinkagePose<T>* pose) const;

  LinkageGeometry geometry_;
  double gh_mm_ = 0.0;       // |GH| of the rigid beam
  double ef_mm_ = 0.0;       // L8
  double guide_side_ = 1.0;  // sign(x_G − x_C) in the reference pose
  double branch_j_ = 1.0;    // sign of cross(G − B, J − B) in the reference pose
  double branch_k_ = 1.0;    // sign of cross(H − A, K − A) in the reference pose
};

// ---------------------------------------------------------------------------------------------
// Template definitions.

namespace internal {

template <typename T>
T Sqr(const T& v) {
  return v * v;
}

// The intersection of circle(p0, r0) and circle(p1, r1) with the smaller y; false if they do not
// meet.
template <typename T>
bool LowerIntersection(const Vec2<T>& p0, const T& r0, const Vec2<T>& p1, const T& r1,
                       Vec2<T>* out) {
  using std::sqrt;
  const T dx = p1.x - p0.x;
  const T dy = p1.y - p0.y;
  const T d2 = dx * dx + dy * dy;
  if (!(d2 > T(0.0))) return false;
  const T d = sqrt(d2);
  const T a = (r0 * r0 - r1 * r1 + d2) / (T(2.0) * d);
  const T h2 = r0 * r0 - a * a;
  if (h2 < T(0.0)) return false;
  const T h = sqrt(h2);
  const T ux = dx / d;
  const T uy = dy / d;
  const T mx = p0.x + a * ux;
  const T my = p0.y + a * uy;
  // n = (−uy, ux); the lower point moves against n when n points up.
  const T sign = (ux > T(0.0)) ? T(-1.0) : T(1.0);
  out->x = mx - sign * h * uy;
  out->y = my + sign * h * ux;
  return true;
}

}  // namespace internal

template <typename T>
bool Linkage::BeamFromPins(const Vec2<T>& g, const Vec2<T>& h, LinkagePose<T>* pose) const {
  const auto& geo = geometry_;
  const double v0x = geo.h0.x - geo.g0.x;
  const double v0y = geo.h0.y - geo.g0.y;
  const double v0_2 = v0x * v0x + v0y * v0y;
  const T vx = h.x - g.x;
  const T vy = h.y - g.y;
  // Rotation taking the zero-pose GH onto the actual GH (|GH| is preserved by the assembly).
  const T c = (vx * v0x + vy * v0y) / v0_2;
  const T s = (vy * v0x - vx * v0y) / v0_2;
  auto place = [&](const Point2& p0) {
    const double rx = p0.x - geo.g0.x;
    const double ry = p0.y - geo.g0.y;
    return Vec2<T>{g.x + c * rx - s * ry, g.y + s * rx + c * ry};
  };
  pose->e = place(geo.e0);
  pose->f = place(geo.f0);
  pose->g = g;
  pose->h = h;
  return true;
}

template <typename T>
bool Linkage::Forward(const T& beta1_deg, const T& beta2_deg, Intermesh<T>* y,
                      LinkagePose<T>* pose) const {
  using std::cos;
  using std::sin;
  const auto& geo = geometry_;
  const double kDegToRad = std::numbers::pi / 180.0;
  const T b1 = beta1_deg * kDegToRad;
  const T b2 = beta2_deg * kDegToRad;
  LinkagePose<T> p;
  p.k = {geo.a.x + geo.ak_mm * cos(b1), geo.a.y + geo.ak_mm * sin(b1)};
  p.j = {geo.b.x + geo.bj_mm * cos(b2), geo.b.y + geo.bj_mm * sin(b2)};
  const Vec2<T> c{T(geo.c.x), T(geo.c.y)};
  Vec2<T> g, h;
  if (!internal::LowerIntersection(c, T(geo.cg_mm), p.j, T(geo.gj_mm), &g)) return false;
  if (!internal::LowerIntersection(g, T(gh_mm_), p.k, T(geo.hk_mm), &h)) return false;
  BeamFromPins(g, h, &p);
  const double top = geo.lower_y_mm + geo.roll_diameter_mm;
  y->y1 = top - p.e.y;
  y->y2 = top - p.f.y;
  y->y3 = T(2.0) * y->y2 - y->y1;
  if (pose != nullptr) *pose = p;
  return true;
}

template <typename T>
bool Linkage::ForwardLengths(const T& ah_mm, const T& bg_mm, Intermesh<T>* y,
                             LinkagePose<T>* pose) const {
  const auto& geo = geometry_;
  LinkagePose<T> p;
  const Vec2<T> a{T(geo.a.x), T(geo.a.y)};
  const Vec2<T> b{T(geo.b.x), T(geo.b.y)};
  const Vec2<T> c{T(geo.c.x), T(geo.c.y)};
  Vec2<T> g, h;
  if (!internal::LowerIntersection(c, T(geo.cg_mm), b, bg_mm, &g)) return false;
  if (!internal::LowerIntersection(g, T(gh_mm_), a, ah_mm, &h)) return false;
  BeamFromPins(g, h, &p);
  p.j = b;
  p.k = a;
  const double top = geo.lower_y_mm + geo.roll_diameter_mm;
  y->y1 = top - p.e.y;
  y->y2 = top - p.f.y;
  y->y3 = T(2.0) * y->y2 - y->y1;
  if (pose != nullptr) *pose = p;
  return true;
}

}  // namespace millkit::leveller
