#include "millkit/balancer/balancer_report.h"

#include <toml++/toml.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <numbers>

#include "balancer/balancer_toml.h"
#include "millkit/io/number_format.h"

namespace millkit::balancer {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

}  // namespace

std::string BalancerResultJson(const BalancerInput& input, const BalancerResult& r) {
  nlohmann::json inputs = nlohmann::json::object();
  const toml::table document = ToToml(input);
  for (const auto& [section, keys] : TomlLayout()) {
    const auto* table = document.get_as<toml::table>(section);
    for (const auto& key : keys) {
      const auto* node = table->get(key);
      if (node->is_integer()) {
        inputs[section][key] = node->as_integer()->get();
      } else {
        inputs[section][key] = node->as_floating_point()->get();
      }
    }
  }
  nlohmann::json j;
  j["input"] = inputs;
  j["support"] = {{"beta_exact_deg", r.support.beta_exact_rad * kDegPerRad},
                  {"beta_deg", r.support.beta_rad * kDegPerRad},
                  {"P1_N", r.support.p1_N},
                  {"P2_N", r.support.p2_N}};
  j["roller"] = {{"span_m", r.roller.span_m},
                 {"q_N_per_m", r.roller.q_N_per_m},
                 {"N1_N", r.roller.n1_N},
                 {"N2_N", r.roller.n2_N},
                 {"x1_m", input.roller.support_offset_m},
                 {"M_x1_Nm", r.roller.moment_at_load_start_Nm},
                 {"x2_m", input.roller.support_offset_m + input.roller.half_loaded_length_m},
                 {"M_x2_Nm", r.roller.moment_at_middle_Nm}};
  j["contact"] = {{"roller_load_N", r.contact.roller_load_N},
                  {"design_load_N", r.contact.design_load_N},
                  {"stress_Pa", r.contact.stress_Pa},
                  {"allowable_Pa", r.contact.allowable_Pa},
                  {"passes", r.contact.passes}};
  j["axle"] = {{"Pp_N", r.axle.pp_N}, {"N3_N", r.axle.n3_N}, {"N4_N", r.axle.n4_N},
               {"RA_N", r.axle.ra_N}, {"RB_N", r.axle.rb_N}, {"M_Nm", r.axle.moment_Nm}};
  j["cross"] = {{"N_N", r.cross.reaction_N},
                {"M_Nm", r.cross.moment_Nm},
                {"safety_factor", r.cross.safety_factor},
                {"allowable_stress_Pa", r.cross.allowable_stress_Pa},
                {"min_diameter_m", r.cross.min_diameter_m},
                {"adopted_diameter_m", input.cross.pin_diameter_m},
                {"stress_at_adopted_Pa", r.cross.stress_at_adopted_Pa},
                {"passes", r.cross.adopted_diameter_passes}};
  j["idle_gaps"] = {{"imbalance_percent", r.gaps.imbalance_percent},
                    {"state", std::string(ToString(r.gaps.state))},
                    {"gaps_open_at_idle", r.gaps.gaps_open_at_idle},
                    {"gap_position", r.gaps.gap_position}};
  j["all_checks_pass"] = r.AllChecksPass();
  return j.dump(2) + "\n";
}

std::string FormatBalancerTable(const BalancerInput& input, const BalancerResult& r) {
  std::string out;
  auto row = [&out](const std::string& name, const std::string& value, const std::string& unit) {
    char buffer[160];
    std::snprintf(buffer, sizeof(buffer), "  %-36s %16s  %s\n", name.c_str(), value.c_str(),
                  unit.c_str());
    out += buffer;
  };
  auto verdict = [](bool passes) { return passes ? std::string("passes") : std::string("FAILS"); };
  out += "Spindle balancing device (docs/balancer.md, seed 002)\n";
  out += "Roller support\n";
  row("beta = arctan(lp/D), exact", FixedNumber(r.support.beta_exact_rad * kDegPerRad, 3), "deg");
  row("beta as used", FixedNumber(r.support.beta_rad * kDegPerRad, 3), "deg");
  row("P1 = Q / (4 cos(alpha + 2 beta))", FixedNumber(r.support.p1_N, 1), "N");
  row("P2 = Q / (4 cos alpha)", FixedNumber(r.support.p2_N, 1), "N");
  out += "Roller (beam, load P1 over 2b)\n";
  row("q = P1 / (2b)", FixedNumber(r.roller.q_N_per_m, 1), "N/m");
  row("N1 = N2", FixedNumber(r.roller.n1_N, 1), "N");
  row("M(x1 = " + FixedNumber(input.roller.support_offset_m * 1e3, 1) + " mm)",
      FixedNumber(r.roller.moment_at_load_start_Nm, 1), "N*m");
  row("M(x2 = " +
          FixedNumber((input.roller.support_offset_m + input.roller.half_loaded_length_m) * 1e3,
                      1) +
          " mm), maximum",
      FixedNumber(r.roller.moment_at_middle_Nm, 1), "N*m");
  out += "Roller contact\n";
  row("Pr = (G + Q) / n", FixedNumber(r.contact.roller_load_N, 1), "N");
  row("Pv = k gamma Pr", FixedNumber(r.contact.design_load_N, 1), "N");
  row("sigma = 0.418 sqrt(Pv E / (b r))", FixedNumber(r.contact.stress_Pa / 1e6, 1), "MPa");
  row("allowable [sigma]", FixedNumber(r.contact.allowable_Pa / 1e6, 1),
      "MPa  " + verdict(r.contact.passes));
  out += "Roller axle\n";
  row("Pp = Q / (2 cos(alpha + beta))", FixedNumber(r.axle.pp_N, 1), "N");
  row("N3 = N4 = Pp / 2", FixedNumber(r.axle.n3_N, 1), "N");
  row("RA", FixedNumber(r.axle.ra_N, 1), "N");
  row("RB", FixedNumber(r.axle.rb_N, 1), "N");
  row("M = N3 a", FixedNumber(r.axle.moment_Nm, 1), "N*m");
  out += "Cardan cross pin\n";
  row("N = G / 2", FixedNumber(r.cross.reaction_N, 1), "N");
  row("M = N a", FixedNumber(r.cross.moment_Nm, 2), "N*m");
  row("S = S1 S2 S3", FixedNumber(r.cross.safety_factor, 3), "");
  row("[sigma] = sigma_u / S", FixedNumber(r.cross.allowable_stress_Pa / 1e6, 1), "MPa");
  row("d_min = cbrt(M / (0.1 [sigma]))", FixedNumber(r.cross.min_diameter_m * 1e3, 1), "mm");
  row("stress at adopted d = " + FixedNumber(input.cross.pin_diameter_m * 1e3, 1) + " mm",
      FixedNumber(r.cross.stress_at_adopted_Pa / 1e6, 1),
      "MPa  " + verdict(r.cross.adopted_diameter_passes));
  out += "Balancing and idle gaps (seed 000)\n";
  row("balancing force", FixedNumber(input.balance.balancing_force_N, 1), "N");
  row("force for exact balance", FixedNumber(input.balance.required_force_N, 1), "N");
  row(r.gaps.imbalance_percent >= 0.0 ? "over-balance" : "under-balance",
      FixedNumber(r.gaps.imbalance_percent, 2), "%");
  const char* gap_note = r.gaps.state == IdleGapState::kClosed ? "(taken up)"
                         : r.gaps.state == IdleGapState::kOpen
                             ? "(open at every angle)"
                             : "(open and close as the hinge turns)";
  row("hinge gaps at idle", std::string(ToString(r.gaps.state)), gap_note);
  row("gap_position for the scene's [[link]]", FixedNumber(r.gaps.gap_position, 3), "");
  return out;
}

}  // namespace millkit::balancer
