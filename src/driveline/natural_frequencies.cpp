#include "millkit/driveline/natural_frequencies.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

namespace millkit::driveline {

std::vector<double> ModalFrequenciesHz(const Scene& reduced, const Reduction& reduction,
                                       GapStiffness gaps) {
  const int groups =
      reduction.group_of_mass.empty()
          ? 0
          : 1 + *std::max_element(reduction.group_of_mass.begin(), reduction.group_of_mass.end());
  if (groups == 0) return {};
  Eigen::VectorXd inertia = Eigen::VectorXd::Zero(groups);
  for (size_t i = 0; i < reduced.masses.size(); ++i) {
    inertia[reduction.group_of_mass[i]] += reduced.masses[i].inertia_kg_m2;
  }
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(groups, groups);
  for (size_t l = 0; l < reduced.links.size(); ++l) {
    if (reduction.link_rigid[l]) continue;
    const Link& link = reduced.links[l];
    const bool stiffest = gaps == GapStiffness::kStiffestPiece && link.backlash_rad > 0.0;
    const double c = stiffest ? StiffestPieceStiffness(reduced.contact, link.stiffness_Nm_per_rad)
                              : link.stiffness_Nm_per_rad;
    const int a = reduction.group_of_mass[link.from], b = reduction.group_of_mass[link.to];
    k(a, a) += c;
    k(b, b) += c;
    k(a, b) -= c;
    k(b, a) -= c;
  }
  const Eigen::VectorXd inv_sqrt = inertia.cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd scaled = inv_sqrt.asDiagonal() * k * inv_sqrt.asDiagonal();
  const double infinite = std::numeric_limits<double>::infinity();
  if (!scaled.allFinite()) return std::vector<double>(groups, infinite);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scaled, Eigen::EigenvaluesOnly);
  if (eigen.info() != Eigen::Success || !eigen.eigenvalues().allFinite()) {
    return std::vector<double>(groups, infinite);
  }
  std::vector<double> hz(groups);
  for (int i = 0; i < groups; ++i) {
    hz[i] = std::sqrt(std::max(0.0, eigen.eigenvalues()[i])) / (2.0 * std::numbers::pi);
  }
  std::sort(hz.begin(), hz.end());
  return hz;
}

std::vector<double> NaturalFrequenciesHz(const driveline::Scene& scene) {
  // Gear stages: on the reference shaft (inertia and stiffness · k²) the tree is ratio-free.
  const Scene reduced = ReducedScene(scene);
  Reduction none;
  none.link_rigid.assign(reduced.links.size(), false);
  none.group_of_mass.resize(reduced.masses.size());
  std::iota(none.group_of_mass.begin(), none.group_of_mass.end(), 0);
  return ModalFrequenciesHz(reduced, none, GapStiffness::kSpring);
}

double LowestNaturalFrequencyHz(const driveline::Scene& scene) {
  const std::vector<double> hz = NaturalFrequenciesHz(scene);
  return hz.size() < 2 ? 0.0 : hz[1];
}

}  // namespace millkit::driveline
