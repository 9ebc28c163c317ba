#include "millkit/balancer/balancer_input.h"

#include <cmath>
#include <functional>
#include <map>
#include <span>

#include "balancer/balancer_toml.h"
#include "io/toml_section.h"
#include "millkit/balancer/roller_support.h"
#include "millkit/io/input_error.h"

namespace millkit::balancer {
namespace {

// One key of the TOML layout and the field it fills. Exactly one of `number`, `integer` is set.
struct Field {
  const char* section;
  const char* key;
  double* (*number)(BalancerInput&);
  int* (*integer)(BalancerInput&);
};

#define MILLKIT_NUMBER_FIELD(section, key, member)                      \
  Field {                                                               \
    section, key, [](BalancerInput& in) { return &in.member; }, nullptr \
  }

std::span<const Field> Fields() {
  static const Field fields[] = {
      MILLKIT_NUMBER_FIELD("load", "support_load_N", loads.support_load_N),
      MILLKIT_NUMBER_FIELD("load", "rod_weight_share_N", loads.rod_weight_share_N),
      MILLKIT_NUMBER_FIELD("support", "alpha_deg", support.alpha_deg),
      MILLKIT_NUMBER_FIELD("support", "roller_spacing_m", support.roller_spacing_m),
      MILLKIT_NUMBER_FIELD("support", "shaft_diameter_m", support.shaft_diameter_m),
      MILLKIT_NUMBER_FIELD("support", "beta_rounding_deg", support.beta_rounding_deg),
      MILLKIT_NUMBER_FIELD("roller", "support_offset_m", roller.support_offset_m),
      MILLKIT_NUMBER_FIELD("roller", "half_loaded_length_m", roller.half_loaded_length_m),
      MILLKIT_NUMBER_FIELD("contact", "diameter_m", contact.diameter_m),
      MILLKIT_NUMBER_FIELD("contact", "width_m", contact.width_m),
      Field{"contact", "count", nullptr, [](BalancerInput& in) { return &in.contact.count; }},
      MILLKIT_NUMBER_FIELD("contact", "elastic_modulus_Pa", contact.elastic_modulus_Pa),
      MILLKIT_NUMBER_FIELD("contact", "allowable_stress_Pa", contact.allowable_stress_Pa),
      MILLKIT_NUMBER_FIELD("contact", "duty_factor", contact.duty_factor),
      MILLKIT_NUMBER_FIELD("contact", "load_variability_factor", contact.load_variability_factor),
      MILLKIT_NUMBER_FIELD("axle", "support_span_m", axle.support_span_m),
      MILLKIT_NUMBER_FIELD("axle", "overhang_m", axle.overhang_m),
      MILLKIT_NUMBER_FIELD("cross", "pin_arm_m", cross.pin_arm_m),
      MILLKIT_NUMBER_FIELD("cross", "pin_diameter_m", cross.pin_diameter_m),
      MILLKIT_NUMBER_FIELD("cross", "ultimate_strength_Pa", cross.ultimate_strength_Pa),
      MILLKIT_NUMBER_FIELD("cross", "s1", cross.s1),
      MILLKIT_NUMBER_FIELD("cross", "s2", cross.s2),
      MILLKIT_NUMBER_FIELD("cross", "s3", cross.s3),
      MILLKIT_NUMBER_FIELD("balance", "required_force_N", balance.required_force_N),
      MILLKIT_NUMBER_FIELD("balance", "balancing_force_N", balance.balancing_force_N),
      MILLKIT_NUMBER_FIELD("balance", "closed_within_percent", balance.closed_within_percent),
      MILLKIT_NUMBER_FIELD("balance", "open_beyond_percent", balance.open_beyond_percent),
  };
  return fields;
}

#undef MILLKIT_NUMBER_FIELD

// Bound on integer keys so that the conversion to int is exact; no device has more rollers.
constexpr double kLargestCount = 1.0e6;

// Collects the first broken rule; later checks are skipped once one has fired.
class RuleCheck {
 public:
  void Positive(const char* section, const char* key, double value) {
    Require(value > 0.0, section, key, "must be > 0 (got " + FormatNumber(value) + ")");
  }
  void NonNegative(const char* section, const char* key, double value) {
    Require(value >= 0.0, section, key, "must be >= 0 (got " + FormatNumber(value) + ")");
  }
  void AtLeast(const char* section, const char* key, double value, double low) {
    Require(value >= low, section, key,
            "must be >= " + FormatNumber(low) + " (got " + FormatNumber(value) + ")");
  }
  void Require(bool holds, const char* section, const char* key, const std::string& rule) {
    if (!holds && !violation_) violation_ = InputViolation{section, key, rule};
  }
  bool ok() const { return !violation_; }
  const std::optional<InputViolation>& violation() const { return violation_; }

 private:
  std::optional<InputViolation> violation_;
};

}  // namespace

bool TomlLayoutHas(std::string_view section, std::string_view key) {
  for (const auto& [name, keys] : TomlLayout()) {
    if (name != section) continue;
    if (key.empty()) return true;
    for (const auto& k : keys) {
      if (k == key) return true;
    }
  }
  return false;
}

BalancerInput SeedCase() { return BalancerInput{}; }

std::optional<InputViolation> FindInputViolation(const BalancerInput& in) {
  RuleCheck check;
  check.Positive("load", "support_load_N", in.loads.support_load_N);
  check.Positive("load", "rod_weight_share_N", in.loads.rod_weight_share_N);

  const auto& s = in.support;
  check.Require(s.alpha_deg >= 0.0 && s.alpha_deg < 90.0, "support", "alpha_deg",
                "must lie in [0, 90) (got " + FormatNumber(s.alpha_deg) + ")");
  check.Positive("support", "roller_spacing_m", s.roller_spacing_m);
  check.Positive("support", "shaft_diameter_m", s.shaft_diameter_m);
  check.Require(s.beta_rounding_deg >= 0.0 && s.beta_rounding_deg <= 5.0, "support",
                "beta_rounding_deg",
                "must lie in [0, 5] (got " + FormatNumber(s.beta_rounding_deg) + ")");
  if (check.ok()) {
    // P1 = Q / (4 cos(α + 2β)) needs cos(α + 2β) > 0; then cos(α + β) > 0 for Pp as well.
    const double beta_deg = SupportBetaDeg(s);
    const double angle_deg = s.alpha_deg + 2.0 * beta_deg;
    check.Require(angle_deg < 90.0, "support", "alpha_deg",
                  "alpha + 2*beta must be < 90 deg so that cos(alpha + 2*beta) > 0 (alpha = " +
                      FormatNumber(s.alpha_deg) + ", beta = " + FormatNumber(beta_deg) +
                      " from arctan(roller_spacing_m / shaft_diameter_m), sum " +
                      FormatNumber(angle_deg) + ")");
  }

  check.NonNegative("roller", "support_offset_m", in.roller.support_offset_m);
  check.Positive("roller", "half_loaded_length_m", in.roller.half_loaded_length_m);

  const auto& c = in.contact;
  check.Positive("contact", "diameter_m", c.diameter_m);
  check.Positive("contact", "width_m", c.width_m);
  check.AtLeast("contact", "count", c.count, 1.0);
  check.Positive("contact", "elastic_modulus_Pa", c.elastic_modulus_Pa);
  check.Positive("contact", "allowable_stress_Pa", c.allowable_stress_Pa);
  check.Positive("contact", "duty_factor", c.duty_factor);
  check.Positive("contact", "load_variability_factor", c.load_variability_factor);

  check.Positive("axle", "support_span_m", in.axle.support_span_m);
  check.NonNegative("axle", "overhang_m", in.axle.overhang_m);

  const auto& x = in.cross;
  check.NonNegative("cross", "pin_arm_m", x.pin_arm_m);
  check.Positive("cross", "pin_diameter_m", x.pin_diameter_m);
  check.Positive("cross", "ultimate_strength_Pa", x.ultimate_strength_Pa);
  check.AtLeast("cross", "s1", x.s1, 1.0);
  check.AtLeast("cross", "s2", x.s2, 1.0);
  check.AtLeast("cross", "s3", x.s3, 1.0);

  const auto& b = in.balance;
  check.Positive("balance", "required_force_N", b.required_force_N);
  check.NonNegative("balance", "balancing_force_N", b.balancing_force_N);
  check.NonNegative("balance", "closed_within_percent", b.closed_within_percent);
  check.Require(b.open_beyond_percent >= b.closed_within_percent, "balance", "open_beyond_percent",
                "must be >= closed_within_percent = " + FormatNumber(b.closed_within_percent) +
                    " (got " + FormatNumber(b.open_beyond_percent) + ")");
  return check.violation();
}

void Validate(const BalancerInput& input) {
  if (const auto v = FindInputViolation(input)) {
    throw InputError("balancer input: [" + v->section + "] key '" + v->key + "': " + v->rule);
  }
}

const std::vector<std::pair<std::string, std::vector<std::string>>>& TomlLayout() {
  static const auto layout = [] {
    std::vector<std::pair<std::string, std::vector<std::string>>> sections;
    for (const auto& field : Fields()) {
      if (sections.empty() || sections.back().first != field.section) {
        sections.emplace_back(field.section, std::vector<std::string>{});
      }
      sections.back().second.emplace_back(field.key);
    }
    return sections;
  }();
  return layout;
}

BalancerInput ReadBalancerInput(const toml::table& document, const std::string& file) {
  const TomlSection root(document, file, "");
  std::string table_names;
  for (const auto& [name, keys] : TomlLayout()) {
    table_names += (table_names.empty() ? "" : ", ") + name;
  }
  for (const auto& [key, node] : document) {
    if (!TomlLayoutHas(key.str()))
      root.Fail(key.str(), "unknown table (allowed: " + table_names + ")");
  }

  std::map<std::string, TomlSection, std::less<>> sections;
  for (const auto& [name, keys] : TomlLayout()) {
    const auto section = root.OptionalTable(name);
    if (!section) root.Fail(name, "is required (a table [" + name + "])");
    std::string allowed;
    for (const auto& k : keys) allowed += (allowed.empty() ? "" : ", ") + k;
    for (const auto& [key, node] : section->table()) {
      if (!TomlLayoutHas(name, key.str())) {
        section->Fail(key.str(), "unknown key (allowed here: " + allowed + ")");
      }
    }
    sections.emplace(name, *section);
  }

  BalancerInput input;
  for (const auto& field : Fields()) {
    const TomlSection& section = sections.at(field.section);
    const double value = section.RequiredNumber(field.key);
    if (field.number != nullptr) {
      *field.number(input) = value;
      continue;
    }
    if (!section.table().get(field.key)->is_integer()) {
      section.Fail(field.key, "must be an integer (got " + FormatNumber(value) + ")");
    }
    if (std::abs(value) > kLargestCount) {
      section.Fail(field.key, "must be <= " + FormatNumber(kLargestCount) + " (got " +
                                  FormatNumber(value) + ")");
    }
    *field.integer(input) = static_cast<int>(value);
  }

  if (const auto v = FindInputViolation(input)) sections.at(v->section).Fail(v->key, v->rule);
  return input;
}

BalancerInput ReadBalancerInputFile(const std::filesystem::path& path) {
  return ReadBalancerInput(LoadTomlFile(path), path.string());
}

toml::table ToToml(const BalancerInput& input) {
  BalancerInput copy = input;
  toml::table document;
  for (const auto& field : Fields()) {
    if (!document.contains(field.section)) document.insert(field.section, toml::table{});
    auto* section = document.get_as<toml::table>(field.section);
    if (field.number != nullptr) {
      section->insert(field.key, *field.number(copy));
    } else {
      section->insert(field.key, static_cast<int64_t>(*field.integer(copy)));
    }
  }
  return document;
}

}  // namespace millkit::balancer
