// `millkit balancer`: the spindle balancing device calculator (SPEC.md §7, §8; issue 6).
// Parses the device (TOML or the built-in seed case) and flag overrides, calls the library,
// prints its table on stdout and writes its JSON result atomically with --out
// (balancer_report.h). No physics and no result formatting here.
#include <toml++/toml.h>

#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "balancer/balancer_toml.h"
#include "cli/commands.h"
#include "io/toml_section.h"
#include "millkit/balancer/balancer.h"
#include "millkit/balancer/balancer_report.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/input_error.h"
#include "millkit/io/output_files.h"

namespace millkit::cli {
namespace {

namespace bal = millkit::balancer;

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
      WriteFileAtomically(options->out, bal::BalancerResultJson(input, result));
    }
    std::cout << bal::FormatBalancerTable(input, result);
  });
}

}  // namespace millkit::cli
