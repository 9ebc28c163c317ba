#include "millkit/balancer/roller_support.h"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "millkit/io/number_format.h"

namespace millkit::balancer {
namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;

// Coefficient of the line-contact stress formula for two steel bodies (ν = 0.3), seed 002 §3.
constexpr double kLineContactCoefficient = 0.418;

void Require(bool holds, const char* function, const std::string& rule) {
  if (!holds) throw std::invalid_argument(std::string(function) + ": " + rule);
}

std::string Got(double value) { return " (got " + FormatNumber(value) + ")"; }

}  // namespace

double ExactSupportBetaRad(const SupportGeometry& geometry) {
  Require(geometry.roller_spacing_m > 0.0, "ExactSupportBetaRad",
          "roller_spacing_m must be > 0" + Got(geometry.roller_spacing_m));
  Require(geometry.shaft_diameter_m > 0.0, "ExactSupportBetaRad",
          "shaft_diameter_m must be > 0" + Got(geometry.shaft_diameter_m));
  return std::atan(geometry.roller_spacing_m / geometry.shaft_diameter_m);
}

double SupportBetaDeg(const SupportGeometry& geometry) {
  const double exact_deg = ExactSupportBetaRad(geometry) / kRadPerDeg;
  Require(geometry.beta_rounding_deg >= 0.0, "SupportBetaDeg",
          "beta_rounding_deg must be >= 0" + Got(geometry.beta_rounding_deg));
  if (geometry.beta_rounding_deg == 0.0) return exact_deg;
  // Rounded in degrees, where the step is stated, so that 17.5° stays exactly 17.5.
  return geometry.beta_rounding_deg * std::round(exact_deg / geometry.beta_rounding_deg);
}

double SupportBetaRad(const SupportGeometry& geometry) {
  return SupportBetaDeg(geometry) * kRadPerDeg;
}

SupportReactions CalcSupportReactions(double support_load_N, const SupportGeometry& geometry) {
  Require(support_load_N >= 0.0, "CalcSupportReactions",
          "support_load_N must be >= 0" + Got(support_load_N));
  const double alpha = geometry.alpha_deg * kRadPerDeg;
  SupportReactions r;
  r.beta_exact_rad = ExactSupportBetaRad(geometry);
  r.beta_rad = SupportBetaRad(geometry);
  // The angle rule in degrees, as stated: cos(90°) evaluates to 6e-17, not 0, in radians.
  const double beta_deg = SupportBetaDeg(geometry);
  Require(geometry.alpha_deg >= 0.0 && geometry.alpha_deg + 2.0 * beta_deg < 90.0,
          "CalcSupportReactions",
          "need alpha >= 0 and alpha + 2*beta < 90 deg (cos(alpha + 2*beta) > 0)" +
              Got(geometry.alpha_deg));
  r.p1_N = support_load_N / (4.0 * std::cos(alpha + 2.0 * r.beta_rad));
  r.p2_N = support_load_N / (4.0 * std::cos(alpha));
  return r;
}

RollerBending CalcRollerBending(double p1_N, const RollerBeam& beam) {
  Require(p1_N >= 0.0, "CalcRollerBending", "p1_N must be >= 0" + Got(p1_N));
  Require(beam.support_offset_m >= 0.0, "CalcRollerBending",
          "support_offset_m must be >= 0" + Got(beam.support_offset_m));
  Require(beam.half_loaded_length_m > 0.0, "CalcRollerBending",
          "half_loaded_length_m must be > 0" + Got(beam.half_loaded_length_m));
  const double a = beam.support_offset_m;
  const double b = beam.half_loaded_length_m;
  RollerBending r;
  r.span_m = 2.0 * a + 2.0 * b;
  r.q_N_per_m = p1_N / (2.0 * b);
  r.n1_N = p1_N * (a + b) / r.span_m;
  r.n2_N = r.n1_N;
  r.moment_at_load_start_Nm = RollerBendingMomentAt(p1_N, beam, a);
  r.moment_at_middle_Nm = RollerBendingMomentAt(p1_N, beam, a + b);
  return r;
}

double RollerBendingMomentAt(double p1_N, const RollerBeam& beam, double x_m) {
  const double a = beam.support_offset_m;
  const double b = beam.half_loaded_length_m;
  const double span = 2.0 * a + 2.0 * b;
  if (!(x_m > 0.0 && x_m < span)) return 0.0;
  // The beam is symmetric: measure from the nearer support.
  const double x = std::min(x_m, span - x_m);
  const double q = p1_N / (2.0 * b);
  const double n1 = p1_N * (a + b) / span;
  const double loaded = std::max(0.0, x - a);
  return n1 * x - q * loaded * loaded / 2.0;
}

double LineContactStressPa(double force_N, double modulus_Pa, double width_m, double radius_m) {
  Require(force_N >= 0.0, "LineContactStressPa", "force_N must be >= 0" + Got(force_N));
  Require(modulus_Pa > 0.0, "LineContactStressPa", "modulus_Pa must be > 0" + Got(modulus_Pa));
  Require(width_m > 0.0, "LineContactStressPa", "width_m must be > 0" + Got(width_m));
  Require(radius_m > 0.0, "LineContactStressPa", "radius_m must be > 0" + Got(radius_m));
  return kLineContactCoefficient * std::sqrt(force_N * modulus_Pa / (width_m * radius_m));
}

ContactCheck CalcRollerContact(double support_load_N, double rod_weight_share_N,
                               const RollerContact& contact) {
  Require(support_load_N >= 0.0, "CalcRollerContact",
          "support_load_N must be >= 0" + Got(support_load_N));
  Require(rod_weight_share_N >= 0.0, "CalcRollerContact",
          "rod_weight_share_N must be >= 0" + Got(rod_weight_share_N));
  Require(contact.count >= 1, "CalcRollerContact", "count must be >= 1" + Got(contact.count));
  Require(contact.duty_factor > 0.0 && contact.load_variability_factor > 0.0, "CalcRollerContact",
          "duty_factor and load_variability_factor must be > 0");
  Require(contact.allowable_stress_Pa > 0.0, "CalcRollerContact",
          "allowable_stress_Pa must be > 0" + Got(contact.allowable_stress_Pa));
  ContactCheck r;
  r.roller_load_N = (rod_weight_share_N + support_load_N) / contact.count;
  r.design_load_N = contact.duty_factor * contact.load_variability_factor * r.roller_load_N;
  r.stress_Pa = LineContactStressPa(r.design_load_N, contact.elastic_modulus_Pa, contact.width_m,
                                    contact.diameter_m / 2.0);
  r.allowable_Pa = contact.allowable_stress_Pa;
  r.passes = r.stress_Pa <= r.allowable_Pa;
  return r;
}

AxleLoads CalcRollerAxle(double support_load_N, const SupportGeometry& geometry,
                         const RollerAxle& axle) {
  Require(support_load_N >= 0.0, "CalcRollerAxle",
          "support_load_N must be >= 0" + Got(support_load_N));
  Require(axle.support_span_m > 0.0, "CalcRollerAxle",
          "support_span_m must be > 0" + Got(axle.support_span_m));
  Require(axle.overhang_m >= 0.0, "CalcRollerAxle",
          "overhang_m must be >= 0" + Got(axle.overhang_m));
  const double alpha = geometry.alpha_deg * kRadPerDeg;
  Require(geometry.alpha_deg >= 0.0 && geometry.alpha_deg + SupportBetaDeg(geometry) < 90.0,
          "CalcRollerAxle",
          "need alpha >= 0 and alpha + beta < 90 deg (cos(alpha + beta) > 0)" +
              Got(geometry.alpha_deg));
  const double cos_pp = std::cos(alpha + SupportBetaRad(geometry));
  const double a = axle.overhang_m;
  const double b = axle.support_span_m;
  AxleLoads r;
  r.pp_N = support_load_N / (2.0 * cos_pp);
  r.n3_N = r.pp_N / 2.0;
  r.n4_N = r.pp_N / 2.0;
  r.rb_N = (r.n4_N * (b + a) - r.n3_N * a) / b;
  r.ra_N = r.n3_N + r.n4_N - r.rb_N;
  r.moment_Nm = std::max(r.n3_N, r.n4_N) * a;
  return r;
}

}  // namespace millkit::balancer
