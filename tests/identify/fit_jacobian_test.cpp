// The fit's Jacobian from sensitivities (issue 15 item 1): ProjectedResidual with
// Derivatives::kSensitivity against central differences of the same projected residual.
// identify/fit_model.h comes first: glog (through Ceres) defines CHECK, which Catch's replaces.
// clang-format off
#include "identify/fit_model.h"
// clang-format on

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <stdexcept>

#include "identify/instrument_filter.h"
#include "identify/random_line.h"
#include "identify/uncertainty.h"
#include "millkit/driveline/model.h"
#include "millkit/driveline/scene.h"
#include "millkit/driveline/simulation.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"
#include "support/run_cli.h"

namespace millkit {

// The torques' derivatives chained with the parameter map, the gains and offsets solved again,
// on random lines at random points.
TEST_CASE("The fit's projected Jacobian from sensitivities agrees with central differences",
          "[sensitivity]") {
  std::mt19937_64 random(17);
  int compared = 0;
  double worst = 0.0;
  for (unsigned long seed = 30; seed < 42; ++seed) {
    const auto line = identify::MakeRandomLineCase(seed);
    const std::vector<double> weights(line.config.channels.size(), 1.0);
    const std::vector<identify::Oscillogram> records{line.record};
    const identify::FitModel model(line.prior, records, line.config, weights);
    const int p = model.parameters();
    std::vector<double> phi(p);
    for (double& angle : phi) angle = std::uniform_real_distribution<double>(-1.2, 1.2)(random);
    const double* parameters[] = {phi.data()};
    Eigen::VectorXd r_exact(model.residuals()), r_reference(model.residuals());
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> exact(model.residuals(),
                                                                                 p),
        reference(model.residuals(), p);
    double* jacobian_exact[] = {exact.data()};
    double* jacobian_reference[] = {reference.data()};
    const identify::ProjectedResidual sensitivity(model, 1e-6, identify::Derivatives::kSensitivity);
    const identify::ProjectedResidual central(model, 1e-6, identify::Derivatives::kCentral);
    if (!sensitivity.Evaluate(parameters, r_exact.data(), jacobian_exact)) continue;
    REQUIRE(central.Evaluate(parameters, r_reference.data(), jacobian_reference));
    CHECK(r_exact == r_reference);
    for (int j = 0; j < p; ++j) {
      INFO("seed " << seed << " " << model.slot(j).name);
      const double size = reference.col(j).cwiseAbs().maxCoeff();
      const double difference = (exact.col(j) - reference.col(j)).cwiseAbs().maxCoeff();
      // The differences' own error (step 1e-6 of the unit range: roundoff ≈ 1e-10 of the
      // residuals over 1e-6) bounds what can be checked: 1e-5 of the column's size, or 1e-6 of
      // the largest column for a parameter the residuals hardly depend on (measured: 6e-7).
      CHECK(difference <= 1e-5 * size + 1e-6 * reference.cwiseAbs().maxCoeff());
      worst = std::max(worst, difference / (size + 1e-2 * reference.cwiseAbs().maxCoeff()));
      ++compared;
    }
  }
  CHECK(compared >= 30);
  std::printf("projected Jacobian: %d columns, worst difference %.3g of the column's size\n",
              compared, worst);
}

// The covariance's Jacobian (gains and offsets analytic, scene parameters from the
// sensitivities) against the one from central differences, at random points of random lines:
// the same residuals, the same gain and offset columns, the scene columns within the
// differences' own error.
TEST_CASE("The covariance's Jacobian from sensitivities agrees with central differences",
          "[sensitivity]") {
  std::mt19937_64 random(23);
  int compared = 0, differing = 0;
  for (unsigned long seed = 50; seed < 58; ++seed) {
    const auto line = identify::MakeRandomLineCase(seed);
    const std::vector<double> weights(line.config.channels.size(), 1.0);
    const std::vector<identify::Oscillogram> records{line.record};
    const identify::FitModel model(line.prior, records, line.config, weights);
    std::vector<double> u(model.parameters());
    for (double& value : u) value = std::uniform_real_distribution<double>(0.2, 0.8)(random);
    Eigen::VectorXd r;
    std::vector<identify::Nuisance> nuisance;
    if (!model.ProjectedResiduals(u.data(), &r, &nuisance)) continue;
    Eigen::VectorXd r_exact, r_central;
    Eigen::MatrixXd exact, central;
    REQUIRE(model.FullJacobian(u, nuisance, 1e-6, identify::Derivatives::kSensitivity, &r_exact,
                               &exact));
    REQUIRE(model.FullJacobian(u, nuisance, 1e-6, identify::Derivatives::kCentral, &r_central,
                               &central));
    CHECK(r_exact == r_central);
    REQUIRE(exact.cols() == central.cols());
    const double largest = central.cwiseAbs().maxCoeff();
    for (Eigen::Index j = 0; j < central.cols(); ++j) {
      INFO("seed " << seed << " column " << j);
      const double size = central.col(j).cwiseAbs().maxCoeff();
      const double difference = (exact.col(j) - central.col(j)).cwiseAbs().maxCoeff();
      if (j >= model.parameters()) {
        CHECK(difference == 0.0);  // gains and offsets: the same analytic columns
        continue;
      }
      // Central differences at 1e-6 of the unit range: roundoff ≈ 1e-10 / 1e-6 of the
      // residuals, as in the projected Jacobian's test.
      CHECK(difference <= 1e-5 * size + 1e-6 * largest);
      ++compared;
      if (difference > 0.0) ++differing;  // not the differences themselves
    }
  }
  CHECK(compared >= 20);
  CHECK(differing == compared);
}

// The search asks for the covariance's Jacobian at the best minimum up to three times: the
// second ask at the same point takes no simulation and gives the same bits as computing it
// again (a copy of the model, which starts without the memo); another point, another kind of
// derivative or another window is computed.
TEST_CASE("The covariance's Jacobian at the point just asked is not computed again", "[fit]") {
  const auto line = identify::MakeRandomLineCase(51);
  const std::vector<double> weights(line.config.channels.size(), 1.0);
  const std::vector<identify::Oscillogram> records{line.record};
  identify::FitModel model(line.prior, records, line.config, weights);
  std::vector<double> u(model.parameters(), 0.4);
  Eigen::VectorXd r;
  std::vector<identify::Nuisance> nuisance;
  REQUIRE(model.ProjectedResiduals(u.data(), &r, &nuisance));
  const auto jacobian = [&](const identify::FitModel& m, const std::vector<double>& at,
                            identify::Derivatives kind, Eigen::VectorXd* residuals,
                            Eigen::MatrixXd* j) {
    const long before = m.simulations();
    REQUIRE(m.FullJacobian(at, nuisance, 1e-6, kind, residuals, j));
    return m.simulations() - before;
  };
  const auto sensitivity = identify::Derivatives::kSensitivity;
  Eigen::VectorXd r1, r2, r3;
  Eigen::MatrixXd j1, j2, j3;
  CHECK(jacobian(model, u, sensitivity, &r1, &j1) > 0);
  CHECK(jacobian(model, u, sensitivity, &r2, &j2) == 0);
  CHECK(r2 == r1);
  CHECK(j2 == j1);
  const identify::FitModel copy = model;
  CHECK(jacobian(copy, u, sensitivity, &r3, &j3) > 0);
  CHECK(r3 == r1);
  CHECK(j3 == j1);
  // Another kind of derivative, then another point, then the first point again: each computed.
  CHECK(jacobian(model, u, identify::Derivatives::kCentral, &r3, &j3) > 0);
  std::vector<double> moved = u;
  moved[0] = 0.41;
  CHECK(jacobian(model, moved, sensitivity, &r3, &j3) > 0);
  CHECK(j3 != j1);
  CHECK(jacobian(model, u, sensitivity, &r3, &j3) > 0);
  CHECK(j3 == j1);
  // Another window: the residuals are those of the stage, not the memo's.
  model.SetStage(4.0);
  REQUIRE(model.residuals() < r1.size());
  CHECK(jacobian(model, u, sensitivity, &r3, &j3) > 0);
  CHECK(r3.size() == model.residuals());
  CHECK(j3.rows() == model.residuals());
}

// A plain run streams only the channels' link torques; a run with sensitivities keeps every
// sample. Both go through the recorder filter of the bundled record's channels: the same
// channel samples, bit for bit.
TEST_CASE("A fit's plain and sensitivity runs give the same channel samples", "[sensitivity]") {
  const auto scene = driveline::LoadScene(testing::SourcePath("datasets/scenes/mill5_bite.toml"));
  const auto record =
      identify::LoadOscillogram(testing::SourcePath("datasets/records/mill5_two_spindles.csv"));
  const auto config = identify::LoadFitConfig(
      testing::SourcePath("datasets/records/mill5_two_spindles.fit.toml"), record, scene);
  REQUIRE(std::all_of(config.channels.begin(), config.channels.end(),
                      [](const identify::ChannelSpec& c) { return c.lowpass_Hz > 0.0; }));
  const int end = static_cast<int>(
      std::upper_bound(record.time_s.begin(), record.time_s.end(), 0.3) - record.time_s.begin());
  std::vector<driveline::SceneParameter> parameters;
  for (const auto& free : config.free) parameters.push_back(free.parameter);
  // A window that starts after the record: the filter still runs from the record's start.
  for (const int begin : {0, 100}) {
    std::vector<Eigen::VectorXd> plain, kept;
    std::vector<Eigen::MatrixXd> derivatives;
    std::string why, unavailable;
    REQUIRE(
        identify::SimulateChannels(scene, record, 0.0, config.channels, begin, end, &plain, &why));
    REQUIRE(identify::SimulateChannels(scene, record, 0.0, config.channels, begin, end, &kept, &why,
                                       parameters, &derivatives, &unavailable));
    CHECK(unavailable.empty());
    REQUIRE(plain.size() == config.channels.size());
    REQUIRE(kept.size() == plain.size());
    for (size_t c = 0; c < plain.size(); ++c) {
      CHECK(plain[c].size() == end - begin);
      CHECK(plain[c] == kept[c]);
      CHECK(plain[c].cwiseAbs().maxCoeff() > 1e4);  // N·m: the bite is in the window
    }
  }
}

// The bundled two-spindle record's first 0.3 s (`end` its sample count) with its scene and config;
// `mixed`: its channels and one more on the first channel's link with half its filter's cutoff
// (two filters on one link: the oversampled path); the config's free scene parameters.
struct BundledWindow {
  driveline::Scene scene =
      driveline::LoadScene(testing::SourcePath("datasets/scenes/mill5_bite.toml"));
  identify::Oscillogram record =
      identify::LoadOscillogram(testing::SourcePath("datasets/records/mill5_two_spindles.csv"));
  identify::FitConfig config = identify::LoadFitConfig(
      testing::SourcePath("datasets/records/mill5_two_spindles.fit.toml"), record, scene);
  std::vector<identify::ChannelSpec> mixed;
  int end = 0;
  std::vector<driveline::SceneParameter> parameters;

  BundledWindow() : mixed(config.channels) {
    mixed.push_back(mixed.front());
    mixed.back().lowpass_Hz = 0.5 * mixed.front().lowpass_Hz;
    end = static_cast<int>(std::upper_bound(record.time_s.begin(), record.time_s.end(), 0.3) -
                           record.time_s.begin());
    for (const auto& free : config.free) parameters.push_back(free.parameter);
  }
};

// A fit's plain run keeps its stops; the derivatives along them (ChannelDerivatives) are those of a
// sensitivity run to the bit, with the filter inside the model and applied after an oversampled
// run (two channels of one link with different filters), on a window that starts after the record.
TEST_CASE("A channel's derivatives along a kept plain run are those of a sensitivity run",
          "[sensitivity]") {
  const BundledWindow bundled;
  const auto& [scene, record, config, mixed, end, parameters] = bundled;
  for (const auto& channels : {config.channels, mixed}) {
    for (const int begin : {0, 100}) {
      std::vector<Eigen::VectorXd> plain, kept_torques, with_derivatives;
      std::vector<Eigen::MatrixXd> derivatives, along;
      std::string why, unavailable, along_unavailable;
      driveline::RecordedRun kept;
      REQUIRE(identify::SimulateChannels(scene, record, 0.0, channels, begin, end, &plain, &why));
      REQUIRE(identify::SimulateChannels(scene, record, 0.0, channels, begin, end, &kept_torques,
                                         &why, &kept));
      REQUIRE(identify::SimulateChannels(scene, record, 0.0, channels, begin, end,
                                         &with_derivatives, &why, parameters, &derivatives,
                                         &unavailable));
      REQUIRE(identify::ChannelDerivatives(kept, record, 0.0, channels, begin, end, parameters,
                                           &along, &along_unavailable, &why));
      REQUIRE(unavailable.empty());
      CHECK(along_unavailable.empty());
      REQUIRE(along.size() == channels.size());
      for (size_t c = 0; c < channels.size(); ++c) {
        CHECK(kept_torques[c] == plain[c]);
        CHECK(kept_torques[c] == with_derivatives[c]);
        CHECK(along[c].rows() == end - begin);
        CHECK(along[c].cols() == static_cast<Eigen::Index>(parameters.size()));
        CHECK(along[c] == derivatives[c]);
      }
      // A kept run belongs to its window.
      CHECK_THROWS_AS(identify::ChannelDerivatives(kept, record, 0.0, channels, begin, end - 1,
                                                   parameters, &along, &along_unavailable, &why),
                      std::logic_error);
    }
  }
}

// The recorder filter inside the model (exact at the record's times) and on the model sampled
// kFilterOversample times per record step (the path taken when two channels of one link have
// different filters, linear between the points) give the same channel samples and derivatives to
// that interpolation's error.
TEST_CASE("A channel's recorder filter in the model agrees with the oversampled filter",
          "[sensitivity]") {
  const BundledWindow bundled;
  const auto& [scene, record, config, mixed, end, parameters] = bundled;
  std::vector<Eigen::VectorXd> exact, sampled;
  std::vector<Eigen::MatrixXd> exact_d, sampled_d;
  std::string why, unavailable;
  REQUIRE(identify::SimulateChannels(scene, record, 0.0, config.channels, 0, end, &exact, &why,
                                     parameters, &exact_d, &unavailable));
  REQUIRE(unavailable.empty());
  REQUIRE(identify::SimulateChannels(scene, record, 0.0, mixed, 0, end, &sampled, &why, parameters,
                                     &sampled_d, &unavailable));
  REQUIRE(unavailable.empty());
  for (size_t c = 0; c < config.channels.size(); ++c) {
    const double peak = exact[c].cwiseAbs().maxCoeff();
    const double difference = (exact[c] - sampled[c]).cwiseAbs().maxCoeff();
    INFO("channel " << c << ": " << difference / peak << " of the peak");
    // Linear interpolation over a sixteenth of a 2 kHz record's step: 1.7e-5 and 2.8e-5 of the
    // peak measured (5.5e-4 at a quarter step, 8e-6 at 1/32: second order).
    CHECK(difference <= 5e-5 * peak);
    CHECK(difference > 0.0);  // two different computations
    // A torque's sensitivity jumps in time where an event's kink moves with the parameter: the
    // in-model filter takes the jump rule, the sampled one a line across the jump, off by a few
    // per cent in the samples just after an event (measured: at most 11 of 601, 8 % of the
    // column's size) and to 1e-3 elsewhere.
    for (Eigen::Index j = 0; j < exact_d[c].cols(); ++j) {
      INFO(parameters[j].name);
      const double size = exact_d[c].col(j).cwiseAbs().maxCoeff();
      const Eigen::VectorXd gap = (exact_d[c].col(j) - sampled_d[c].col(j)).cwiseAbs();
      CHECK(gap.maxCoeff() <= 0.15 * size);
      CHECK((gap.array() > 1e-3 * size).count() <= gap.size() / 30);
    }
  }
}

// A filter above half the record's rate runs inside the model too: the exact solver and the
// sensitivity pass carry its state apart from the line's Taylor series, so its rate costs no
// steps. The channels are the in-model filter's exactly (the record's times, no interpolation),
// and the sensitivities come with them.
TEST_CASE("A recorder filter above half the record's rate runs inside the model", "[sensitivity]") {
  const auto scene = driveline::LoadScene(testing::SourcePath("datasets/scenes/mill5_bite.toml"));
  const auto record =
      identify::LoadOscillogram(testing::SourcePath("datasets/records/mill5_two_spindles.csv"));
  auto config = identify::LoadFitConfig(
      testing::SourcePath("datasets/records/mill5_two_spindles.fit.toml"), record, scene);
  const int end = static_cast<int>(
      std::upper_bound(record.time_s.begin(), record.time_s.end(), 0.3) - record.time_s.begin());
  std::vector<driveline::SceneParameter> parameters;
  for (const auto& free : config.free) parameters.push_back(free.parameter);
  for (const double cutoff_Hz : {2000.0, 20000.0}) {  // the record's rate is 2 kHz
    INFO(cutoff_Hz << " Hz");
    driveline::Scene exact_scene = scene;
    for (auto& channel : config.channels) {
      channel.lowpass_Hz = cutoff_Hz;
      exact_scene.links[channel.link_index].recorder_lowpass_Hz = cutoff_Hz;
    }
    std::vector<Eigen::VectorXd> channels;
    std::vector<Eigen::MatrixXd> derivatives;
    std::string why, unavailable;
    REQUIRE(identify::SimulateChannels(scene, record, 0.0, config.channels, 0, end, &channels, &why,
                                       parameters, &derivatives, &unavailable));
    CHECK(unavailable.empty());
    exact_scene.duration_s = record.time_s[end - 1];
    driveline::SimulationOptions options;
    options.output_times = std::vector<double>(record.time_s.begin(), record.time_s.begin() + end);
    const auto exact = driveline::Simulate(driveline::Model(exact_scene), options);
    REQUIRE(exact.summary.success);
    // Against the line sampled 256 times a step and filtered as linear between the points: that
    // reference converges to the in-model filter (20 kHz, the worse channel: 3.0e-5 of the peak
    // at 64 points, 8.7e-6 at 128, 4.4e-7 at 256; 2 kHz: 1.7e-7 and 3.2e-7 at 256).
    std::vector<double> fine;
    for (int k = 0; k + 1 < end; ++k) {
      for (int j = 0; j < 256; ++j) {
        fine.push_back(record.time_s[k] + j * (record.time_s[k + 1] - record.time_s[k]) / 256);
      }
    }
    fine.push_back(record.time_s[end - 1]);
    driveline::Scene plain = scene;
    plain.duration_s = record.time_s[end - 1];
    options.output_times = fine;
    const auto own = driveline::Simulate(driveline::Model(plain), options);
    REQUIRE(own.summary.success);
    for (size_t c = 0; c < config.channels.size(); ++c) {
      const int link = config.channels[c].link_index;
      const Eigen::VectorXd reference = exact.link_torque_Nm.col(link);
      const double peak = reference.cwiseAbs().maxCoeff();
      CHECK((channels[c] - reference).cwiseAbs().maxCoeff() <= 1e-12 * peak);
      const Eigen::VectorXd column = own.link_torque_Nm.col(link);
      std::vector<double> filtered(column.data(), column.data() + column.size());
      identify::FirstOrderLowPass(cutoff_Hz, fine, &filtered);
      double difference = 0.0;
      for (int k = 0; k < end; ++k) {
        difference =
            std::max(difference, std::abs(channels[c][k] - filtered[static_cast<size_t>(k) * 256]));
      }
      INFO("channel " << c << ": " << difference / peak << " of the peak");
      CHECK(difference <= 2e-6 * peak);
      REQUIRE(derivatives[c].cols() == static_cast<Eigen::Index>(parameters.size()));
      CHECK(derivatives[c].allFinite());
    }
  }
}

// A fit iterated with sensitivities and one with forward differences reach the same minimum:
// every value within 0.1 standard error, the same verdict (random lines not used to tune).
TEST_CASE("Fits with sensitivities and with forward differences agree", "[sensitivity]") {
  for (const unsigned long seed : {11ul, 23ul}) {
    INFO("seed " << seed);
    const auto line = identify::MakeRandomLineCase(seed);
    identify::FitOptions options;
    options.derivatives = identify::Derivatives::kSensitivity;
    const auto sensitivity = identify::Fit(line.prior, line.record, line.config, options);
    options.derivatives = identify::Derivatives::kForward;
    const auto forward = identify::Fit(line.prior, line.record, line.config, options);
    REQUIRE(sensitivity.summary.success);
    REQUIRE(forward.summary.success);
    CHECK(sensitivity.summary.verdict == forward.summary.verdict);
    REQUIRE(sensitivity.parameters.size() == forward.parameters.size());
    for (size_t i = 0; i < forward.parameters.size(); ++i) {
      INFO(forward.parameters[i].name);
      CHECK(std::abs(sensitivity.parameters[i].value - forward.parameters[i].value) <=
            0.1 * forward.parameters[i].standard_error);
    }
    // Fewer simulations: one run gives every parameter's column.
    CHECK(sensitivity.summary.simulations < forward.summary.simulations);
  }
}

// The stopping test's measure (FitOptions::remaining_step_se): on a linear least-squares problem
// the Gauss–Newton step is the exact one, so its length in standard errors is known directly.
TEST_CASE("The Gauss-Newton step left is measured in standard errors", "[fit]") {
  std::mt19937_64 random(5);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int n = 60;
  Eigen::MatrixXd j(n, 3);
  Eigen::VectorXd r(n);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) j(i, c) = normal(random);
    r[i] = normal(random);
  }
  // The step δ = −J⁺r; its length under the covariance s² (JᵀJ)⁻¹ is √(δᵀJᵀJδ / s²).
  const Eigen::VectorXd delta = -j.colPivHouseholderQr().solve(r);
  const Eigen::VectorXd after = r + j * delta;
  const double s2 = after.squaredNorm() / (n - 3);
  const double expected = std::sqrt((j * delta).squaredNorm() / s2);
  CHECK(identify::GaussNewtonStepInStandardErrors(j, r) == Approx(expected).epsilon(1e-10));
  // Close to the minimum the step shrinks with the distance to it.
  const Eigen::VectorXd near = after + j * Eigen::Vector3d(1e-3, -2e-3, 5e-4);
  CHECK(identify::GaussNewtonStepInStandardErrors(j, near) < 0.01 * expected);
  // A repeated column (an unidentifiable direction) adds no length.
  Eigen::MatrixXd repeated(n, 4);
  repeated << j, j.col(1);
  CHECK(identify::GaussNewtonStepInStandardErrors(repeated, r) == Approx(expected).epsilon(1e-8));
  // No degree of freedom left: no standard error to measure in.
  CHECK(std::isnan(identify::GaussNewtonStepInStandardErrors(j.topRows(3), r.head(3))));
}

TEST_CASE("A quantity the record hardly depends on is held out of the others' covariance",
          "[fit]") {
  std::mt19937_64 random(29);
  std::normal_distribution<double> normal;
  const int n = 200;
  Eigen::MatrixXd j(n, 3);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) j(i, c) = normal(random);
  }
  // A fourth column nearly along the first: scaled to unit length, it would trade off against it.
  Eigen::VectorXd along(n);
  for (int i = 0; i < n; ++i) along[i] = j(i, 0) + 0.3 * normal(random);
  along.normalize();
  const Eigen::MatrixXd three = identify::Covariance(j, {0, 1, 2}, 1.0);
  for (const double size : {1e-3, 1e-9}) {  // whole-range effect 0.001 and 1e-9 noise units
    INFO("column norm " << size);
    Eigen::MatrixXd four(n, 4);
    four << j, size * along;
    const Eigen::MatrixXd covariance = identify::Covariance(four, {0, 1, 2, 3}, 1.0);
    CHECK((covariance.topLeftCorner(3, 3) - three).norm() <= 1e-12 * three.norm());
    CHECK(covariance(3, 3) == Approx(1.0 / (size * size)).epsilon(1e-12));
    CHECK(covariance.row(3).head(3).isZero(0.0));
  }
  // An effect of 0.1 noise units over the range is kept: the trade-off with the first is real.
  Eigen::MatrixXd kept(n, 4);
  kept << j, 0.1 * along;
  const Eigen::MatrixXd covariance = identify::Covariance(kept, {0, 1, 2, 3}, 1.0);
  CHECK(covariance(0, 0) > 5.0 * three(0, 0));
}

namespace {

// An early stop of the default options, against `full` without it, on random lines: the same
// verdicts, costs within 0.05 (½ χ²), every value within 0.2 SE, and fewer simulations.
void CheckSameFits(const std::vector<unsigned long>& seeds,
                   const identify::FitOptions& full_options, bool fewer_simulations) {
  for (const unsigned long seed : seeds) {
    INFO("seed " << seed);
    const auto line = identify::MakeRandomLineCase(seed);
    const auto stopped = identify::Fit(line.prior, line.record, line.config, {});
    const auto full = identify::Fit(line.prior, line.record, line.config, full_options);
    REQUIRE(stopped.summary.success);
    REQUIRE(full.summary.success);
    CHECK(stopped.summary.verdict == full.summary.verdict);
    CHECK(std::abs(stopped.summary.cost - full.summary.cost) <= 0.05);
    if (fewer_simulations) CHECK(stopped.summary.simulations < full.summary.simulations);
    REQUIRE(stopped.parameters.size() == full.parameters.size());
    for (size_t i = 0; i < full.parameters.size(); ++i) {
      INFO(full.parameters[i].name);
      CHECK(std::abs(stopped.parameters[i].value - full.parameters[i].value) <=
            0.2 * full.parameters[i].standard_error);
    }
  }
}

}  // namespace

// The statistical stop changes no estimate by a visible fraction of its standard error.
TEST_CASE("Fits with and without the remaining-step stop agree", "[fit]") {
  identify::FitOptions full;
  full.remaining_step_se = 0.0;
  full.rough_step_se = 0.0;
  CheckSameFits({4ul, 11ul, 23ul}, full, false);
}

// A hop or direct fit that stops where it comes back to a known minimum (identify/multistart.h)
// changes no verdict or estimate, and saves simulations.
TEST_CASE("Fits with and without the rejoin stop agree", "[fit]") {
  identify::FitOptions full;
  full.rejoin_se = 0.0;
  CheckSameFits({4ul, 23ul, 312ul}, full, true);
}

}  // namespace millkit

namespace millkit {
namespace {

// Levenberg–Marquardt over ProjectedResidual as identify's refinements run it, the iterations
// reported to the residual (ProjectedResidual::EndEarly) or not.
struct LevenbergMarquardtRun {
  std::vector<double> phi;
  size_t iterations = 0;
  ceres::TerminationType termination = ceres::FAILURE;
  double cost = 0.0;
  long simulations = 0;
  std::vector<std::vector<double>> accepted;  // the points of the Jacobians computed
  bool skipped = false;                       // the last Jacobian asked was not computed
  bool stopped = false;
  bool last_step_accepted = false;
};

class ReportIterations final : public ceres::IterationCallback {
 public:
  ReportIterations(const identify::ProjectedResidual& residual, bool report,
                   LevenbergMarquardtRun* run)
      : residual_(residual), report_(report), accepted_(&run->accepted), run_(run) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (report_) residual_.IterationFinished(summary.iteration);
    run_->last_step_accepted = summary.iteration > 0 && summary.step_is_successful;
    if (summary.step_is_successful && !residual_.jacobian_skipped()) {
      accepted_->push_back(residual_.jacobian_point());
    }
    return residual_.stopped() ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
  }

 private:
  const identify::ProjectedResidual& residual_;
  bool report_;
  std::vector<std::vector<double>>* accepted_;
  LevenbergMarquardtRun* run_;
};

LevenbergMarquardtRun RunLevenbergMarquardt(
    const identify::FitModel& model, identify::Derivatives derivatives, std::vector<double> phi,
    int iterations, bool report, std::function<bool(const double*, double)> stop = nullptr) {
  LevenbergMarquardtRun run;
  identify::ProjectedResidual residual(model, 1e-3, derivatives);
  if (report) residual.EndEarly(iterations, std::move(stop));
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  problem.AddResidualBlock(&residual, nullptr, phi.data());
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = iterations;
  options.function_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  options.gradient_tolerance = 1e-20;
  options.logging_type = ceres::SILENT;
  ReportIterations callback(residual, report, &run);
  options.callbacks.push_back(&callback);
  const long before = model.simulations();
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  run.simulations = model.simulations() - before;
  run.phi = phi;
  run.iterations = summary.iterations.size();
  run.termination = summary.termination_type;
  run.cost = summary.final_cost;
  run.skipped = residual.jacobian_skipped();
  run.stopped = residual.stopped();
  return run;
}

}  // namespace

// The Jacobian Levenberg–Marquardt asks for at the point it accepts last, before its iteration
// cap or a stop test ends it there, is never read (identify/multistart.cpp's refinements): it is
// skipped, and the fit ends at the same point to the last bit. With sensitivities that spares the
// pass along the plain run just before (one simulation), with forward differences the P probes.
// A residual that skipped a Jacobian still read would move the next step; one that did not skip
// would cost the simulations.
TEST_CASE("A Jacobian the fit never reads is not computed", "[fit]") {
  for (const auto derivatives :
       {identify::Derivatives::kSensitivity, identify::Derivatives::kForward}) {
    std::mt19937_64 random(5);
    int capped_on_accepted = 0;
    int stopped = 0;
    for (unsigned long seed = 1; seed <= 6; ++seed) {
      INFO("seed " << seed << (derivatives == identify::Derivatives::kForward ? ", forward" : ""));
      const auto line = identify::MakeRandomLineCase(seed);
      const std::vector<double> weights(line.config.channels.size(), 1.0);
      const std::vector<identify::Oscillogram> records{line.record};
      const identify::FitModel model(line.prior, records, line.config, weights);
      std::vector<double> start(model.parameters());
      for (double& angle : start) {
        angle = std::uniform_real_distribution<double>(-0.6, 0.6)(random);
      }
      const long spared = derivatives == identify::Derivatives::kForward ? model.parameters() : 1;
      const auto plain = RunLevenbergMarquardt(model, derivatives, start, 4, false);
      const auto capped = RunLevenbergMarquardt(model, derivatives, start, 4, true);
      CHECK(capped.phi == plain.phi);
      CHECK(capped.iterations == plain.iterations);
      CHECK(capped.termination == plain.termination);
      CHECK(capped.cost == plain.cost);
      // Skipped exactly where the cap ends the fit on an accepted point.
      const bool last_accepted =
          plain.termination == ceres::NO_CONVERGENCE && plain.last_step_accepted;
      CHECK(capped.skipped == last_accepted);
      CHECK(capped.simulations == plain.simulations - (last_accepted ? spared : 0));
      capped_on_accepted += last_accepted ? 1 : 0;
      // A stop test met at the second accepted point: the fit ends there without its Jacobian.
      if (plain.accepted.size() < 3) continue;
      const std::vector<double> second = plain.accepted[2];
      const auto stop = [&second](const double* phi, double /*cost*/) {
        return std::equal(second.begin(), second.end(), phi);
      };
      const auto ended = RunLevenbergMarquardt(model, derivatives, start, 50, true, stop);
      CHECK(ended.stopped);
      CHECK(ended.skipped);
      CHECK(ended.phi == second);
      CHECK(ended.termination == ceres::USER_SUCCESS);
      ++stopped;
    }
    CHECK(capped_on_accepted >= 2);
    CHECK(stopped >= 2);
  }
}

}  // namespace millkit
