// Model pieces the solvers build on (SPEC §2.5): the link torques as a linear map of the state.
#include "millkit/driveline/model.h"

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "hard_scenes.h"
#include "identify/instrument_filter.h"
#include "scene_builder.h"
#include "support/run_cli.h"

using namespace millkit::driveline;
using millkit::driveline::testing::RelativeDifference;

namespace {
// Outputs and T z are the same sums in another order: a few ulps of the largest term.
constexpr double kRoundoff = 1e-12;

void CheckTorqueRows(const Model& model) {
  std::mt19937 random(5);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const int n = model.augmented_size(), nx = model.state_size(), nw = model.forcing_size();
  const Eigen::VectorXd scale = [&] {
    Eigen::VectorXd s = Eigen::VectorXd::Ones(n);
    s.head(nx) = model.StateScale();
    s.segment(nx, nw).setConstant(1e5);
    return s;
  }();
  const int links = static_cast<int>(model.scene().links.size());
  std::vector<double> torque(links), twist(links), speed(model.scene().masses.size());
  for (int phase = 0; phase <= static_cast<int>(LinkPhase::kNegDoubleSpring); ++phase) {
    Phases phases(model.backlash_link_count() + (model.has_drive() ? 1 : 0), '\0');
    for (int k = 0; k < model.backlash_link_count(); ++k) phases[k] = static_cast<char>(phase);
    const Eigen::MatrixXd system = model.SystemMatrix(phases);
    const Eigen::MatrixXd rows = model.LinkTorqueRows(phases, system);
    REQUIRE(rows.rows() == links);
    REQUIRE(rows.cols() == n);
    for (int trial = 0; trial < 5; ++trial) {
      Eigen::VectorXd z(n);
      for (int i = 0; i < n; ++i) z[i] = scale[i] * uniform(random);
      z[nx] = 1.0;       // the constant forcing component
      z[nx + nw] = 0.0;  // and its slope
      model.Outputs(phases, z, torque.data(), speed.data(), twist.data(), &system);
      const Eigen::VectorXd linear = rows * z;
      for (int l = 0; l < links; ++l) {
        const double size = (rows.row(l).cwiseAbs() * z.cwiseAbs())(0);
        CHECK(std::abs(linear[l] - torque[l]) <= kRoundoff * size);
      }
    }
  }
}
}  // namespace

TEST_CASE("The link torque rows reproduce Outputs in every phase", "[model]") {
  CheckTorqueRows(
      Model(LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml"))));
}

TEST_CASE("The link torque rows reproduce Outputs for links made rigid by the band", "[model]") {
  Scene scene = LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_stiff_motor.toml"));
  scene.band_Hz = 20.0;
  scene.sample_rate_Hz = 5000.0;
  const Model model(scene);
  REQUIRE(model.flexible_link_count() < static_cast<int>(scene.links.size()));
  CheckTorqueRows(model);
}

TEST_CASE("The link torque rows reproduce Outputs with a speed drive", "[model]") {
  CheckTorqueRows(Model(LoadScene(millkit::testing::SourcePath("datasets/scenes/drive_pi.toml"))));
}

namespace {
// Runs `scene` with a recorder low-pass on `links` and checks: the exact solver's reported torque
// of each such link is the low-pass of the link's own torque (unfiltered run sampled `fine` times
// per step, filtered as linear between samples: that error falls about as fine⁻², less where an
// event puts a kink between samples: 64 must be 2.5 times closer than 32, and within `reference`
// of the peak), the other links are untouched, CVODE agrees, and T reproduces Outputs.
void CheckRecorderLowPass(Scene scene, const std::vector<int>& links, double cutoff_Hz,
                          double reference = 1e-5) {
  const SimulationResult own = Simulate(Model(scene), {});
  REQUIRE(own.summary.success);
  for (const int l : links) scene.links[l].recorder_lowpass_Hz = cutoff_Hz;
  const Model model(scene);
  const SimulationResult filtered = Simulate(model, {});
  REQUIRE(filtered.summary.success);
  CHECK(filtered.summary.events == own.summary.events);
  const double peak = own.link_torque_Nm.cwiseAbs().maxCoeff();
  double error[2] = {0.0, 0.0};
  double fine_difference = 0.0;  // the filtered torque, run on the coarse and on the fine grids
  const int fines[2] = {32, 64};
  for (int i = 0; i < 2; ++i) {
    SimulationOptions options;
    std::vector<double> times;
    const double h = 1.0 / scene.sample_rate_Hz;
    for (int k = 0; k + 1 < scene.SampleCount(); ++k) {
      for (int j = 0; j < fines[i]; ++j)
        times.push_back((k + static_cast<double>(j) / fines[i]) * h);
    }
    times.push_back((scene.SampleCount() - 1) * h);
    options.output_times = times;
    const SimulationResult fine = Simulate(Model(scene), options);
    REQUIRE(fine.summary.success);
    // The fine run reports filtered torques: the reference filters the own run's instead (the
    // record generator's filter, exact for a signal linear between its samples).
    Scene plain = scene;
    for (auto& link : plain.links) link.recorder_lowpass_Hz = 0.0;
    const SimulationResult fine_own = Simulate(Model(plain), options);
    REQUIRE(fine_own.summary.success);
    for (const int l : links) {
      const Eigen::VectorXd column = fine_own.link_torque_Nm.col(l);
      std::vector<double> reference(column.data(), column.data() + column.size());
      millkit::identify::FirstOrderLowPass(cutoff_Hz, times, &reference);
      for (int k = 0; k < scene.SampleCount(); ++k) {
        const double value = filtered.link_torque_Nm(k, l);
        error[i] =
            std::max(error[i], std::abs(value - reference[static_cast<size_t>(k) * fines[i]]));
        fine_difference =
            std::max(fine_difference,
                     std::abs(fine.link_torque_Nm(static_cast<size_t>(k) * fines[i], l) - value));
      }
    }
  }
  INFO("filtered against the low-pass of the fine runs, per peak: "
       << error[0] / peak << " (" << fines[0] << "), " << error[1] / peak << " (" << fines[1]
       << ")");
  // The same state on 32 and 64 times the steps: roundoff only (1.1e-10 of the peak measured on
  // the five-mass bite).
  CHECK(fine_difference <= 1e-9 * peak);
  CHECK(error[1] <= reference * peak);
  CHECK(error[1] <= 0.4 * error[0]);
  for (int l = 0; l < static_cast<int>(scene.links.size()); ++l) {
    if (std::find(links.begin(), links.end(), l) != links.end()) continue;
    CHECK((filtered.link_torque_Nm.col(l) - own.link_torque_Nm.col(l)).cwiseAbs().maxCoeff() <=
          1e-10 * peak);
  }
  SimulationOptions cvode;  // CVODE reads the filter from Outputs and LinearPieces
  cvode.solver = SolverKind::kCvode;
  cvode.rtol = 1e-12;
  const SimulationResult other = Simulate(model, cvode);
  REQUIRE(other.summary.success);
  Scene plain = scene;
  for (auto& link : plain.links) link.recorder_lowpass_Hz = 0.0;
  const SimulationResult other_own = Simulate(Model(plain), cvode);
  // CVODE at 1e-12 is itself 1e-8 to 6e-7 of the peak off the exact solver on these scenes; the
  // filter adds nothing to that (measured: 2.2e-8 against 4.0e-8, 7.2e-7 against 5.5e-7, 1.3e-8
  // against 1.2e-8).
  const double disagreement = RelativeDifference(other.link_torque_Nm, filtered.link_torque_Nm);
  const double own_disagreement = RelativeDifference(other_own.link_torque_Nm, own.link_torque_Nm);
  CHECK(disagreement <= 2.0 * own_disagreement + 1e-9);
  // Both report a filtered rigid link's twist as its reported torque over c.
  CHECK(RelativeDifference(other.link_twist_rad, filtered.link_twist_rad) <=
        2.0 * RelativeDifference(other_own.link_twist_rad, own.link_twist_rad) + 1e-9);
  CheckTorqueRows(model);
}
}  // namespace

TEST_CASE("A recorder low-pass in the model is the filter of the link's own torque", "[model]") {
  SECTION("the five-mass bite, both spindles at 800 Hz") {
    CheckRecorderLowPass(LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml")),
                         {2, 3}, 800.0);
  }
  SECTION("a link made rigid by the band") {
    Scene scene = LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_stiff_motor.toml"));
    scene.band_Hz = 20.0;
    scene.sample_rate_Hz = 5000.0;
    int rigid = -1;
    const Model plain(scene);
    for (int l = 0; l < static_cast<int>(scene.links.size()); ++l) {
      if (plain.reduction().link_rigid[l]) rigid = l;
    }
    REQUIRE(rigid >= 0);
    CheckRecorderLowPass(scene, {rigid}, 300.0);
  }
  SECTION("a speed drive") {
    CheckRecorderLowPass(LoadScene(millkit::testing::SourcePath("datasets/scenes/drive_pi.toml")),
                         {0}, 200.0);
  }
  // Faster than the sampling: the exact solver takes the filter's states apart from the Taylor
  // series of the others (a·h = 6.3 at 2 kHz against 0.5 for the line) and from the bounds of
  // the event search, so that even a·h = 157 (50 kHz) is stepped as the line's own rate asks:
  // the same steps as the unfiltered line, none of them a stiff substep (not counted in steps).
  SECTION("the five-mass bite, both spindles at 2, 8 and 50 kHz") {
    const Scene scene = LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml"));
    const long steps = Simulate(Model(scene), {}).summary.steps;
    for (const double cutoff_Hz : {2000.0, 8000.0, 50000.0}) {
      CheckRecorderLowPass(scene, {2, 3}, cutoff_Hz);
      Scene filtered = scene;
      filtered.links[2].recorder_lowpass_Hz = filtered.links[3].recorder_lowpass_Hz = cutoff_Hz;
      CHECK(Simulate(Model(filtered), {}).summary.steps == steps);
    }
  }
  // Stiff phase sets (hard_scenes.h: a coupling damped at 1e4, ‖m‖ h ≈ 20) are stepped on their
  // ladder of propagators with the filter's states inside. The damping torque follows the load's
  // 1 ms ramp at 1 kHz: the fine runs' filter, linear between points, is itself 1e-4 to 1e-3 of
  // the peak off there (second order: the convergence check holds).
  SECTION("a heavily damped coupling, filtered at 300 Hz and at 50 kHz") {
    CheckRecorderLowPass(testing::HeavyDampingScene(1e4), {0}, 300.0, 2e-3);
    CheckRecorderLowPass(testing::HeavyDampingScene(1e4), {0}, 50000.0, 2e-3);
  }
}

TEST_CASE("A model built for its coefficients has a run's coefficients and no state scale",
          "[model]") {
  Scene scene = LoadScene(millkit::testing::SourcePath("datasets/scenes/drive_pi.toml"));
  scene.links[0].recorder_lowpass_Hz = 200.0;  // its settled initial state reads the phases
  const Model run(scene);
  const Model coefficients(scene, Model::Use::kCoefficients);
  CHECK(coefficients.InitialState() == run.InitialState());
  CHECK(coefficients.InitialPhases() == run.InitialPhases());
  CHECK(coefficients.surfaces() == run.surfaces());
  const Phases& phases = run.InitialPhases();
  CHECK(coefficients.SystemMatrix(phases) == run.SystemMatrix(phases));
  CHECK(coefficients.LinkTorqueRows(phases, coefficients.SystemMatrix(phases)) ==
        run.LinkTorqueRows(phases, run.SystemMatrix(phases)));
  CHECK(run.StateScale().size() == run.state_size());
  CHECK_THROWS_AS(coefficients.StateScale(), std::logic_error);
}
