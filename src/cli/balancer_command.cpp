// `millkit balancer`: the spindle balancing device calculator (SPEC.md §7, §8; issue 6).
// Parses the device (TOML or the built-in seed case) and flag overrides, calls the library,
// prints a table on stdout and writes the JSON result atomically with --out. No physics here.
#include <toml++/toml.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "balancer/balancer_toml.h"
#include "cli/commands.h"
#include "io/toml_section.h"
#include "millkit/balancer/balancer.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/input_error.h"
#include "millkit/io/output_files.h"

namespace millkit::cli {
namespace {

namespace bal = millkit::balancer;

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

struct BalancerOptions {
  std::string config;
  std::string out;
  std::vector<std::string> sets;
  std::optional<double> balancing_force_N;
  std::optional<double> required_force_N;
};

std::string KnownKeys() {
  std::string list;
  for (const auto& [section, keys] : bal::TomlLayout()) {
    for (const auto& key : keys) list += (list.empty() ? "" : ", ") + section + "." + key;
  }
  return list;
}

// Puts `value` at section.key of `document`, creating the table when it is absent.
void Override(toml::table& document, const std::string& section, const std::string& key,
              toml::node&& value) {
  auto* table = document.get_as<toml::table>(section);
  if (table == nullptr) {
    document.insert_or_assign(section, toml::table{});
    table = document.get_as<toml::table>(section);
  }
  table->insert_or_assign(key, std::move(value));
}

// Applies one `--set section.key=value`. The key must be one of the layout and the value a TOML
// number; range rules are checked later with the rest of the input.
void ApplySet(toml::table& document, const std::string& assignment) {
  const std::string flag = "--set '" + assignment + "'";
  const auto equals = assignment.find('=');
  const auto dot = assignment.find('.');
  if (equals == std::string::npos || dot == std::string::npos || dot > equals) {
    throw InputError(flag + ": expected section.key=value, e.g. support.alpha_deg=30");
  }
  const std::string section = assignment.substr(0, dot);
  const std::string key = assignment.substr(dot + 1, equals - dot - 1);
  const std::string text = assignment.substr(equals + 1);
  if (!bal::TomlLayoutHas(section, key) || key.empty()) {
    throw InputError(flag + ": unknown key '" + section + "." + key + "' (known: " + KnownKeys() +
                     ")");
  }
  toml::table parsed;
  try {
    parsed = toml::parse("value = " + text);
  } catch (const toml::parse_error&) {
    throw InputError(flag + ": key '" + section + "." + key + "': must be a number (got '" + text +
                     "')");
  }
  const auto* node = parsed.get("value");
  if (const auto* i = node->as_integer()) {
    Override(document, section, key, toml::value<int64_t>(i->get()));
  } else if (const auto* f = node->as_floating_point()) {
    Override(document, section, key, toml::value<double>(f->get()));
  } else {
    throw InputError(flag + ": key '" + section + "." + key + "': must be a number (got '" + text +
                     "')");
  }
}

bal::BalancerInput LoadInput(const BalancerOptions& options) {
  toml::table document =
      options.config.empty() ? bal::ToToml(bal::SeedCase()) : LoadTomlFile(options.config);
  std::string label = options.config.empty() ? "seed 002 case" : options.config;
  bool overridden = false;
  for (const auto& assignment : options.sets) {
    ApplySet(document, assignment);
    overridden = true;
  }
  if (options.required_force_N) {
    Override(document, "balance", "required_force_N",
             toml::value<double>(*options.required_force_N));
    overridden = true;
  }
  if (options.balancing_force_N) {
    Override(document, "balance", "balancing_force_N",
             toml::value<double>(*options.balancing_force_N));
    overridden = true;
  }
  if (overridden) label += " with command-line overrides";
  return bal::ReadBalancerInput(document, label);
}

nlohmann::json ToJson(const bal::BalancerInput& input, const bal::BalancerResult& r) {
  nlohmann::json inputs = nlohmann::json::object();
  const toml::table document = bal::ToToml(input);
  for (const auto& [section, keys] : bal::TomlLayout()) {
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
                    {"state", std::string(bal::ToString(r.gaps.state))},
                    {"gaps_open_at_idle", r.gaps.gaps_open_at_idle},
                    {"gap_position", r.gaps.gap_position}};
  j["all_checks_pass"] = r.AllChecksPass();
  return j;
}

void PrintTable(std::ostream& out, const bal::BalancerInput& input, const bal::BalancerResult& r) {
  auto row = [&out](const std::string& name, const std::string& value, const std::string& unit) {
    char buffer[160];
    std::snprintf(buffer, sizeof(buffer), "  %-36s %16s  %s\n", name.c_str(), value.c_str(),
                  unit.c_str());
    out << buffer;
  };
  auto verdict = [](bool passes) { return passes ? std::string("passes") : std::string("FAILS"); };
  out << "Spindle balancing device (docs/balancer.md, seed 002)\n";
  out << "Roller support\n";
  row("beta = arctan(lp/D), exact", FixedNumber(r.support.beta_exact_rad * kDegPerRad, 3), "deg");
  row("beta as used", FixedNumber(r.support.beta_rad * kDegPerRad, 3), "deg");
  row("P1 = Q / (4 cos(alpha + 2 beta))", FixedNumber(r.support.p1_N, 1), "N");
  row("P2 = Q / (4 cos alpha)", FixedNumber(r.support.p2_N, 1), "N");
  out << "Roller (beam, load P1 over 2b)\n";
  row("q = P1 / (2b)", FixedNumber(r.roller.q_N_per_m, 1), "N/m");
  row("N1 = N2", FixedNumber(r.roller.n1_N, 1), "N");
  row("M(x1 = " + FixedNumber(input.roller.support_offset_m * 1e3, 1) + " mm)",
      FixedNumber(r.roller.moment_at_load_start_Nm, 1), "N*m");
  row("M(x2 = " +
          FixedNumber((input.roller.support_offset_m + input.roller.half_loaded_length_m) * 1e3,
                      1) +
          " mm), maximum",
      FixedNumber(r.roller.moment_at_middle_Nm, 1), "N*m");
  out << "Roller contact\n";
  row("Pr = (G + Q) / n", FixedNumber(r.contact.roller_load_N, 1), "N");
  row("Pv = k gamma Pr", FixedNumber(r.contact.design_load_N, 1), "N");
  row("sigma = 0.418 sqrt(Pv E / (b r))", FixedNumber(r.contact.stress_Pa / 1e6, 1), "MPa");
  row("allowable [sigma]", FixedNumber(r.contact.allowable_Pa / 1e6, 1),
      "MPa  " + verdict(r.contact.passes));
  out << "Roller axle\n";
  row("Pp = Q / (2 cos(alpha + beta))", FixedNumber(r.axle.pp_N, 1), "N");
  row("N3 = N4 = Pp / 2", FixedNumber(r.axle.n3_N, 1), "N");
  row("RA", FixedNumber(r.axle.ra_N, 1), "N");
  row("RB", FixedNumber(r.axle.rb_N, 1), "N");
  row("M = N3 a", FixedNumber(r.axle.moment_Nm, 1), "N*m");
  out << "Cardan cross pin\n";
  row("N = G / 2", FixedNumber(r.cross.reaction_N, 1), "N");
  row("M = N a", FixedNumber(r.cross.moment_Nm, 2), "N*m");
  row("S = S1 S2 S3", FixedNumber(r.cross.safety_factor, 3), "");
  row("[sigma] = sigma_u / S", FixedNumber(r.cross.allowable_stress_Pa / 1e6, 1), "MPa");
  row("d_min = cbrt(M / (0.1 [sigma]))", FixedNumber(r.cross.min_diameter_m * 1e3, 1), "mm");
  row("stress at adopted d = " + FixedNumber(input.cross.pin_diameter_m * 1e3, 1) + " mm",
      FixedNumber(r.cross.stress_at_adopted_Pa / 1e6, 1),
      "MPa  " + verdict(r.cross.adopted_diameter_passes));
  out << "Balancing and idle gaps (seed 000)\n";
  row("balancing force", FixedNumber(input.balance.balancing_force_N, 1), "N");
  row("force for exact balance", FixedNumber(input.balance.required_force_N, 1), "N");
  row(r.gaps.imbalance_percent >= 0.0 ? "over-balance" : "under-balance",
      FixedNumber(r.gaps.imbalance_percent, 2), "%");
  const char* gap_note = r.gaps.state == bal::IdleGapState::kClosed ? "(taken up)"
                         : r.gaps.state == bal::IdleGapState::kOpen
                             ? "(open at every angle)"
                             : "(open and close as the hinge turns)";
  row("hinge gaps at idle", std::string(bal::ToString(r.gaps.state)), gap_note);
  row("gap_position for the scene's [[link]]", FixedNumber(r.gaps.gap_position, 3), "");
}

}  // namespace

void AddBalancerCommand(CLI::App& app) {
  auto options = std::make_shared<BalancerOptions>();
  auto* command = app.add_subcommand(
      "balancer",
      "Spindle balancing device: support reactions, roller and axle loads, contact and pin "
      "checks, and the idle hinge-gap state for a balancing force (docs/balancer.md)");
  command->add_option("--config", options->config,
                      "Device TOML (every table and key required; default: the seed 002 case)");
  command->add_option("--out", options->out, "Write the result as JSON to this file (atomically)");
  command->add_option("--set", options->sets,
                      "Override one input, section.key=value (e.g. cross.s1=1.2); repeatable");
  command->add_option("--balancing-force", options->balancing_force_N,
                      "Balancing force set on the device, N (balance.balancing_force_N)");
  command->add_option("--required-force", options->required_force_N,
                      "Force that balances the spindle exactly, N (balance.required_force_N)");
  command->callback([options] {
    CheckOutputPaths({{"--out", options->out}}, {options->config});
    const bal::BalancerInput input = LoadInput(*options);
    const bal::BalancerResult result = bal::CalculateBalancer(input);
    if (!options->out.empty()) {
      WriteFileAtomically(options->out, ToJson(input, result).dump(2) + "\n");
    }
    PrintTable(std::cout, input, result);
  });
}

}  // namespace millkit::cli
