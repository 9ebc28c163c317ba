// What `millkit balancer` writes (SPEC.md §7, docs/balancer.md): the result as JSON (every input
// key of the TOML layout, then each check) and the table it prints on the terminal.
#pragma once

#include <string>

#include "millkit/balancer/balancer.h"
#include "millkit/balancer/balancer_input.h"

namespace millkit::balancer {

// JSON text (2-space indent, ending in a newline): "input" (section -> key -> value, the layout of
// TomlLayout()), "support", "roller", "contact", "axle", "cross", "idle_gaps", "all_checks_pass".
// Angles in degrees, everything else in the result's SI units.
std::string BalancerResultJson(const BalancerInput& input, const BalancerResult& result);

// The terminal table: one line per quantity (name, value, unit, and passes/FAILS for a check),
// grouped by part of the device.
std::string FormatBalancerTable(const BalancerInput& input, const BalancerResult& result);

}  // namespace millkit::balancer
