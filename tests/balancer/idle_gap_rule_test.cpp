// The idle-gap rule (idle_gap_rule.h): seed 000's ±3…5 % band, and our reading of it as
// gap_position for a drive-line scene (SPEC.md §2.4).
#include "millkit/balancer/idle_gap_rule.h"

#include <catch2/catch.hpp>
#include <stdexcept>
#include <utility>

namespace bal = millkit::balancer;
using Catch::Matchers::WithinAbs;

namespace {

constexpr double kRoundOff = 1e-12;
constexpr double kExact_N = 100000.0;

bal::BalanceSetting SettingAt(double percent) {
  bal::BalanceSetting setting;  // seed 000 band: 3 % and 5 %
  setting.required_force_N = kExact_N;
  setting.balancing_force_N = kExact_N * (1.0 + percent / 100.0);
  return setting;
}

}  // namespace

TEST_CASE("An exactly balanced spindle keeps its gaps taken up at idle", "[gaps]") {
  const auto r = bal::AssessIdleGaps(SettingAt(0.0));
  CHECK_THAT(r.imbalance_percent, WithinAbs(0.0, kRoundOff));
  CHECK(r.state == bal::IdleGapState::kClosed);
  CHECK_FALSE(r.gaps_open_at_idle);
  CHECK(r.gap_position == 1.0);
}

TEST_CASE("A spindle within 3 percent of balance keeps its gaps taken up", "[gaps]") {
  // Seed 000: a setting within ±3…5 % of exact balance takes up both hinge gaps; 3 % is the end
  // of the band that holds for every spindle (our reading).
  for (const double percent : {-2.99, -1.0, 1.0, 2.99}) {
    const auto r = bal::AssessIdleGaps(SettingAt(percent));
    CHECK(r.state == bal::IdleGapState::kClosed);
    CHECK(r.gap_position == 1.0);
  }
}

TEST_CASE("A spindle more than 5 percent off balance opens its gaps at idle", "[gaps]") {
  // Seed 000: beyond the band the radial forces in the hinges open the gaps; SPEC.md §2.4's worst
  // case: the back flank, gap_position = −1.
  for (const double percent : {-40.0, -5.01, 5.01, 12.0}) {
    const auto r = bal::AssessIdleGaps(SettingAt(percent));
    CHECK(r.state == bal::IdleGapState::kOpen);
    CHECK(r.gaps_open_at_idle);
    CHECK(r.gap_position == -1.0);
  }
}

TEST_CASE("The imbalance is signed: over-balance positive, under-balance negative", "[gaps]") {
  CHECK_THAT(bal::AssessIdleGaps(SettingAt(7.5)).imbalance_percent, WithinAbs(7.5, 1e-9));
  CHECK_THAT(bal::AssessIdleGaps(SettingAt(-7.5)).imbalance_percent, WithinAbs(-7.5, 1e-9));
}

TEST_CASE("Over- and under-balance by the same amount give the same gap position", "[gaps]") {
  // Seed 000 names under-balancing and over-balancing alike as causes of open gaps.
  for (const double percent : {0.5, 3.5, 4.0, 4.9, 6.0}) {
    CHECK_THAT(bal::AssessIdleGaps(SettingAt(percent)).gap_position,
               WithinAbs(bal::AssessIdleGaps(SettingAt(-percent)).gap_position, 1e-9));
  }
}

TEST_CASE("Between 3 and 5 percent the gaps open intermittently, mid-band at mid-gap", "[gaps]") {
  // Our linear blend: gap_position = 1 − 2 (|δ| − 3) / (5 − 3); 4 % → 0, 3.5 % → 0.5.
  const auto mid = bal::AssessIdleGaps(SettingAt(4.0));
  CHECK(mid.state == bal::IdleGapState::kIntermittent);
  CHECK(mid.gaps_open_at_idle);
  CHECK_THAT(mid.gap_position, WithinAbs(0.0, 1e-9));
  CHECK_THAT(bal::AssessIdleGaps(SettingAt(-3.5)).gap_position, WithinAbs(0.5, 1e-9));
}

TEST_CASE("The gap position stays in [-1, 1] and never rises as the imbalance grows", "[gaps]") {
  double previous = 1.0;
  for (int i = 0; i <= 200; ++i) {
    const double percent = 0.05 * i;  // 0 … 10 %
    const double position = bal::AssessIdleGaps(SettingAt(percent)).gap_position;
    CHECK(position >= -1.0);
    CHECK(position <= 1.0);
    CHECK(position <= previous + kRoundOff);
    previous = position;
  }
}

TEST_CASE("Equal band limits switch straight from closed to open", "[gaps]") {
  for (const auto& [percent, expected] :
       {std::pair{3.9, bal::IdleGapState::kClosed}, std::pair{4.1, bal::IdleGapState::kOpen}}) {
    auto setting = SettingAt(percent);
    setting.closed_within_percent = 4.0;
    setting.open_beyond_percent = 4.0;
    CHECK(bal::AssessIdleGaps(setting).state == expected);
  }
}

TEST_CASE("A zero force for exact balance is refused", "[gaps]") {
  auto setting = SettingAt(0.0);
  setting.required_force_N = 0.0;
  CHECK_THROWS_AS(bal::AssessIdleGaps(setting), std::invalid_argument);
}

TEST_CASE("The gap states have readable names", "[gaps]") {
  CHECK(bal::ToString(bal::IdleGapState::kClosed) == "closed");
  CHECK(bal::ToString(bal::IdleGapState::kIntermittent) == "intermittent");
  CHECK(bal::ToString(bal::IdleGapState::kOpen) == "open");
}
