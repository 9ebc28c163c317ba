// Seeded random drive lines (issue 12): a seed names one case, and every case keeps the ranges
// identify/random_line.h states.
#include "identify/random_line.h"

#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <set>
#include <string>
#include <vector>

using namespace millkit;
using namespace millkit::identify;

namespace {

constexpr int kSeeds = 50;
constexpr double kTwoPi = 6.283185307179586476925;

// The non-zero modes by another route than the generator's (symmetric J^-1/2 K J^-1/2 instead of
// the generalized solver), so that a bug in one does not hide in both.
std::vector<double> ModesHz(const driveline::Scene& scene) {
  const int n = static_cast<int>(scene.masses.size());
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(n, n);
  for (const auto& link : scene.links) {
    const double c = link.stiffness_Nm_per_rad;
    k(link.from, link.from) += c;
    k(link.to, link.to) += c;
    k(link.from, link.to) -= c;
    k(link.to, link.from) -= c;
  }
  Eigen::VectorXd inv_sqrt(n);
  for (int i = 0; i < n; ++i) inv_sqrt[i] = 1.0 / std::sqrt(scene.masses[i].inertia_kg_m2);
  const Eigen::MatrixXd scaled = inv_sqrt.asDiagonal() * k * inv_sqrt.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scaled, Eigen::EigenvaluesOnly);
  std::vector<double> modes;
  for (int i = 1; i < n; ++i) modes.push_back(std::sqrt(eigen.eigenvalues()[i]) / kTwoPi);
  return modes;
}

}  // namespace

TEST_CASE("random line: the same seed gives an identical case and another seed a different one") {
  const RandomLineCase a = MakeRandomLineCase(17);
  const RandomLineCase b = MakeRandomLineCase(17);
  const RandomLineCase other = MakeRandomLineCase(18);
  CHECK(a.description == b.description);
  CHECK(a.record.channels == b.record.channels);
  CHECK(a.record.time_s == b.record.time_s);
  CHECK(a.record.values == b.record.values);  // exact: the same draws and the same simulation
  CHECK(a.truth_values == b.truth_values);
  CHECK(a.record.values != other.record.values);
}

TEST_CASE("random line: fifty seeds stay inside the stated ranges") {
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const RandomLineCase c = MakeRandomLineCase(seed);
    INFO("seed " << seed << ": " << c.description);
    CHECK(c.seed == static_cast<unsigned long>(seed));
    CHECK(c.truth.masses.size() >= 2);
    CHECK(c.truth.masses.size() <= 6);
    CHECK(c.truth.links.size() == c.truth.masses.size() - 1);

    const std::vector<double> modes = ModesHz(c.truth);
    CHECK(modes.size() == c.truth.masses.size() - 1);
    for (double f : modes) {
      CHECK(f >= kMinModeHz);
      CHECK(f <= kMaxModeHz);
    }

    CHECK_FALSE(c.record.channels.empty());
    CHECK(c.record.channels.size() <= 3);
    const std::set<std::string> distinct(c.record.channels.begin(), c.record.channels.end());
    CHECK(distinct.size() == c.record.channels.size());
    CHECK(c.config.channels.size() == c.record.channels.size());
    for (const auto& column : c.record.channels) {
      bool mapped = false;
      for (const auto& channel : c.config.channels) mapped = mapped || channel.column == column;
      CHECK(mapped);
    }

    REQUIRE(c.truth_values.size() == c.config.free.size());
    for (size_t i = 0; i < c.truth_values.size(); ++i) {
      INFO(c.config.free[i].parameter.name << " = " << c.truth_values[i]);
      CHECK(c.truth_values[i] >= c.config.free[i].lower);
      CHECK(c.truth_values[i] <= c.config.free[i].upper);
    }

    CHECK(c.record.time_s.size() >= static_cast<size_t>(kMinRecordSamples));
    bool finite = true;
    for (const auto& values : c.record.values) {
      CHECK(values.size() == c.record.time_s.size());
      for (double v : values) finite = finite && std::isfinite(v);
    }
    CHECK(finite);
  }
}

TEST_CASE("random line variants change only what they name, each within its stated ranges") {
  for (unsigned long seed = 1; seed <= 20; ++seed) {
    const RandomLineCase base = MakeRandomLineCase(seed);
    INFO("seed " << seed << ": " << base.description);
    REQUIRE(MakeRandomLineCase(seed, RandomLineVariant::kBase).record.values == base.record.values);

    const RandomLineCase drive = MakeRandomLineCase(seed, RandomLineVariant::kDrive);
    REQUIRE(drive.truth.drive.has_value());
    REQUIRE(drive.prior.drive.has_value());
    const double bandwidth = drive.truth.drive->kp / drive.truth.masses[0].inertia_kg_m2;
    CHECK(bandwidth >= kTwoPi * 5.0 * (1.0 - 1e-12));
    CHECK(bandwidth <= kTwoPi * 20.0 * (1.0 + 1e-12));
    CHECK(drive.record.values != base.record.values);
    CHECK(drive.record.time_s == base.record.time_s);
    CHECK(drive.truth_values == base.truth_values);
    CHECK(drive.prior.links[0].damping_Nms_per_rad == base.prior.links[0].damping_Nms_per_rad);

    const RandomLineCase wide = MakeRandomLineCase(seed, RandomLineVariant::kWidePrior);
    CHECK(wide.record.values == base.record.values);
    REQUIRE(wide.config.free.size() == base.config.free.size());
    for (size_t l = 0; l < wide.truth.links.size(); ++l) {
      const double factor =
          wide.prior.links[l].damping_Nms_per_rad / wide.truth.links[l].damping_Nms_per_rad;
      CHECK(std::abs(std::log(factor)) <= std::log(3.0) + 1e-12);
    }
    for (size_t i = 0; i < wide.config.free.size(); ++i) {
      CHECK(wide.truth_values[i] >= wide.config.free[i].lower);
      CHECK(wide.truth_values[i] <= wide.config.free[i].upper);
    }

    const RandomLineCase stiff = MakeRandomLineCase(seed, RandomLineVariant::kStiffness);
    REQUIRE(stiff.config.free.size() == base.config.free.size() + 1);
    const FreeParameter& k = stiff.config.free.back();
    CHECK(k.parameter.kind == driveline::SceneParameter::Kind::kStiffness);
    CHECK(k.scan);
    CHECK(stiff.truth_values.back() >= k.lower);
    CHECK(stiff.truth_values.back() <= k.upper);
    CHECK(std::abs(std::log(k.start / stiff.truth_values.back())) <= std::log(1.3) + 1e-12);

    const RandomLineCase no_pull = MakeRandomLineCase(seed, RandomLineVariant::kNoPull);
    CHECK(no_pull.truth.contact == driveline::ContactLaw::kNoPull);
    CHECK(no_pull.prior.contact == driveline::ContactLaw::kNoPull);
    CHECK(no_pull.truth_values == base.truth_values);
    CHECK(no_pull.record.time_s == base.record.time_s);

    const RandomLineCase linear = MakeRandomLineCase(seed, RandomLineVariant::kLinear);
    CHECK(linear.truth.contact == driveline::ContactLaw::kLinear);
    CHECK(linear.prior.contact == driveline::ContactLaw::kLinear);
    CHECK(linear.truth_values == base.truth_values);
    CHECK(linear.record.time_s == base.record.time_s);
    bool any_gap = false;
    for (const auto& link : base.truth.links) any_gap = any_gap || link.backlash_rad > 0.0;
    CHECK((linear.record.values != base.record.values) == any_gap);

    const RandomLineCase step = MakeRandomLineCase(seed, RandomLineVariant::kStepLoad);
    REQUIRE(step.truth.torques.size() == base.truth.torques.size());
    for (size_t i = 0; i < step.truth.torques.size(); ++i) {
      const auto& source = step.truth.torques[i];
      CHECK(source.times_s.front() == source.times_s.back());
      CHECK(source.times_s.front() == base.truth.torques[i].times_s.front());
      CHECK(source.values_Nm == base.truth.torques[i].values_Nm);
      CHECK(step.prior.torques[i].times_s.front() == step.prior.torques[i].times_s.back());
    }
    CHECK(step.record.values != base.record.values);
    CHECK(step.record.time_s == base.record.time_s);
    CHECK(step.truth_values == base.truth_values);

    const RandomLineCase lowpass = MakeRandomLineCase(seed, RandomLineVariant::kLowpass);
    const double cutoff = lowpass.record_spec.defects.lowpass_Hz;
    const double rate = base.record_spec.defects.sample_rate_Hz;
    CHECK(cutoff >= 0.1 * rate * (1.0 - 1e-12));
    CHECK(cutoff <= 0.4 * rate * (1.0 + 1e-12));
    CHECK(base.record_spec.defects.lowpass_Hz == 0.0);
    for (const auto& channel : lowpass.config.channels) CHECK(channel.lowpass_Hz == cutoff);
    CHECK(lowpass.record.values != base.record.values);
    CHECK(lowpass.truth_values == base.truth_values);
    const RandomLineCase fast = MakeRandomLineCase(seed, RandomLineVariant::kFastLowpass);
    CHECK(fast.record_spec.defects.lowpass_Hz >= 0.5 * rate * (1.0 - 1e-12));
    CHECK(fast.record_spec.defects.lowpass_Hz <= 5.0 * rate * (1.0 + 1e-12));
    CHECK(fast.record_spec.defects.oversample == 64);
    for (const auto& channel : fast.config.channels) {
      CHECK(channel.lowpass_Hz == fast.record_spec.defects.lowpass_Hz);
    }
    CHECK(fast.record.values != lowpass.record.values);

    // Combined: each variant as alone (the first with its own stream), the filter over the law.
    const RandomLineCase both = MakeRandomLineCase(
        seed,
        std::vector<RandomLineVariant>{RandomLineVariant::kNoPull, RandomLineVariant::kLowpass});
    CHECK(both.truth.contact == driveline::ContactLaw::kNoPull);
    CHECK(both.record_spec.defects.lowpass_Hz > 0.0);
    for (const auto& channel : both.config.channels) {
      CHECK(channel.lowpass_Hz == both.record_spec.defects.lowpass_Hz);
    }
    const RandomLineCase wide_lowpass = MakeRandomLineCase(
        seed,
        std::vector<RandomLineVariant>{RandomLineVariant::kWidePrior, RandomLineVariant::kLowpass});
    CHECK(wide_lowpass.prior.links[0].damping_Nms_per_rad ==
          wide.prior.links[0].damping_Nms_per_rad);
  }
  std::vector<RandomLineVariant> parsed;
  CHECK(ParseRandomLineVariants("no-pull+lowpass", &parsed));
  CHECK(parsed ==
        std::vector<RandomLineVariant>{RandomLineVariant::kNoPull, RandomLineVariant::kLowpass});
  CHECK(ParseRandomLineVariants("fast-lowpass", &parsed));
  CHECK(parsed == std::vector<RandomLineVariant>{RandomLineVariant::kFastLowpass});
  CHECK(ParseRandomLineVariants("drive", &parsed));
  CHECK(parsed.size() == 1);
  CHECK_FALSE(ParseRandomLineVariants("no-pull+", &parsed));
  CHECK_FALSE(ParseRandomLineVariants("no-pull+nothing", &parsed));
  CHECK_FALSE(ParseRandomLineVariants("", &parsed));
}
