#include "millkit/driveline/natural_frequencies.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace millkit::driveline {

std::vector<double> NaturalFrequenciesHz(const driveline::Scene& given) {
  // Gear stages: on the reference shaft (inertia and stiffness · k²) the tree is ratio-free.
  const driveline::Scene scene = ReducedScene(given);
  const int n = static_cast<int>(scene.masses.size());
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) j(i, i) = scene.masses[i].inertia_kg_m2;
  for (const auto& link : scene.links) {
    const double c = link.stiffness_Nm_per_rad;
    k(link.from, link.from) += c;
    k(link.to, link.to) += c;
    k(link.from, link.to) -= c;
    k(link.to, link.from) -= c;
  }
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> solver(k, j, Eigen::EigenvaluesOnly);
  std::vector<double> hz(n);
  for (int i = 0; i < n; ++i) {
    hz[i] = std::sqrt(std::max(0.0, solver.eigenvalues()[i])) / (2.0 * std::numbers::pi);
  }
  std::sort(hz.begin(), hz.end());
  return hz;
}

double LowestNaturalFrequencyHz(const driveline::Scene& scene) {
  const std::vector<double> hz = NaturalFrequenciesHz(scene);
  return hz.size() < 2 ? 0.0 : hz[1];
}

}  // namespace millkit::driveline
