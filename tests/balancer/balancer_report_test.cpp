// The balancer's result writers (balancer_report.h): the JSON carries the input and the computed
// values exactly; the table prints the computed values to its stated decimals.
#include "millkit/balancer/balancer_report.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <string>

#include "millkit/io/number_format.h"

namespace bal = millkit::balancer;
using Catch::Matchers::WithinAbs;

namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// The value and unit columns of the table line whose name column starts with `name`; empty when
// there is none.
std::pair<std::string, std::string> TableCells(const std::string& table, const std::string& name) {
  std::istringstream lines(table);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind("  " + name, 0) != 0 || line.size() < 2 + 36 + 1 + 16) continue;
    std::string value = line.substr(2 + 36 + 1, 16);
    value.erase(0, value.find_first_not_of(' '));
    const std::string unit =
        line.size() > 2 + 36 + 1 + 16 + 2 ? line.substr(2 + 36 + 1 + 16 + 2) : "";
    return {value, unit};
  }
  return {};
}

}  // namespace

TEST_CASE("The balancer JSON carries every input key and the computed values exactly",
          "[balancer][report]") {
  bal::BalancerInput input = bal::SeedCase();
  input.balance.balancing_force_N = 116000.0;
  input.cross.s1 = 1.2;
  const bal::BalancerResult result = bal::CalculateBalancer(input);
  const std::string text = bal::BalancerResultJson(input, result);
  REQUIRE(text.back() == '\n');
  const auto json = nlohmann::json::parse(text);
  for (const auto& [section, keys] : bal::TomlLayout()) {
    for (const auto& key : keys) {
      INFO(section << "." << key);
      CHECK(json["input"][section].contains(key));
    }
  }
  CHECK(json["input"]["balance"]["balancing_force_N"].get<double>() == 116000.0);
  CHECK(json["input"]["cross"]["s1"].get<double>() == 1.2);
  CHECK(json["support"]["P1_N"].get<double>() == result.support.p1_N);
  CHECK(json["support"]["beta_deg"].get<double>() == result.support.beta_rad * kDegPerRad);
  CHECK(json["roller"]["M_x2_Nm"].get<double>() == result.roller.moment_at_middle_Nm);
  CHECK(json["contact"]["stress_Pa"].get<double>() == result.contact.stress_Pa);
  CHECK(json["axle"]["RB_N"].get<double>() == result.axle.rb_N);
  CHECK(json["cross"]["safety_factor"].get<double>() == result.cross.safety_factor);
  CHECK(json["cross"]["adopted_diameter_m"].get<double>() == input.cross.pin_diameter_m);
  CHECK(json["idle_gaps"]["imbalance_percent"].get<double>() == result.gaps.imbalance_percent);
  CHECK(json["idle_gaps"]["state"].get<std::string>() ==
        std::string(bal::ToString(result.gaps.state)));
  CHECK(json["all_checks_pass"].get<bool>() == result.AllChecksPass());
}

TEST_CASE("The balancer table prints the computed values and names a failing check",
          "[balancer][report]") {
  bal::BalancerInput input = bal::SeedCase();
  input.cross.pin_diameter_m = 0.02;  // far below d_min: the pin check fails
  input.balance.balancing_force_N = 100000.0;
  const bal::BalancerResult result = bal::CalculateBalancer(input);
  REQUIRE_FALSE(result.cross.adopted_diameter_passes);
  const std::string table = bal::FormatBalancerTable(input, result);
  const auto p1 = TableCells(table, "P1 = Q / (4 cos(alpha + 2 beta))");
  CHECK(p1.first == millkit::FixedNumber(result.support.p1_N, 1));
  CHECK(p1.second == "N");
  CHECK_THAT(std::stod(p1.first), WithinAbs(result.support.p1_N, 0.05));
  const auto pin = TableCells(table, "stress at adopted d = 20.0 mm");
  CHECK(pin.first == millkit::FixedNumber(result.cross.stress_at_adopted_Pa / 1e6, 1));
  CHECK(pin.second == "MPa  FAILS");
  const auto gap = TableCells(table, "under-balance");
  CHECK(gap.first == millkit::FixedNumber(result.gaps.imbalance_percent, 2));
  CHECK(TableCells(table, "over-balance").first.empty());
  CHECK(TableCells(table, "hinge gaps at idle").first ==
        std::string(bal::ToString(result.gaps.state)));
}
