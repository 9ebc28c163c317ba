// Private: the balancer input as a parsed TOML document (balancer_input.h names the layout). The
// command line applies its overrides to the document before reading it; the public interface reads
// files only (ReadBalancerInputFile), so toml++ stays out of the public headers.
#pragma once

#include <toml++/toml.h>

#include <string>

#include "millkit/balancer/balancer_input.h"

namespace millkit::balancer {

// Reads a complete device description. `file` labels the messages. Throws InputError naming file,
// table, key and line: unknown table or key, missing table or key, a value that is not a number,
// and every rule of FindInputViolation().
BalancerInput ReadBalancerInput(const toml::table& document, const std::string& file);

// The TOML form of `input` (the layout ReadBalancerInput reads); ReadBalancerInput(ToToml(x)) == x.
toml::table ToToml(const BalancerInput& input);

}  // namespace millkit::balancer
