// Model pieces the solvers build on (SPEC §2.5): the link torques as a linear map of the state.
#include "millkit/driveline/model.h"

#include <catch2/catch.hpp>
#include <random>

#include "scene_builder.h"
#include "support/run_cli.h"

using namespace millkit::driveline;

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
