// Undamped natural frequencies of a drive-line scene with every gap closed (SPEC.md §2.1, §5):
// the tree of inertias J and links of stiffness c, K φ = ω² J φ with
//   K = Σ_links c (e_from − e_to)(e_from − e_to)ᵀ,  J = diag(J_k),
// solved as a generalized self-adjoint eigenproblem (Eigen::GeneralizedSelfAdjointEigenSolver).
// Every link counts with its stiffness c (the spring-damper piece of its contact law, the
// coupling's catalogue stiffness), on the scene reduced to its reference shaft (ReducedScene:
// gear ratios count); no band reduction, no drive states (the speed controller is
// the drive's business, not the coupling's). A tree of N masses has one rigid-body mode (ω = 0)
// and N − 1 elastic modes.
//
// Each elastic frequency is nondecreasing in every link stiffness (adding a positive
// semidefinite term to K; Weyl's inequality), so the lowest one is largest at the stiffest bounds.
#pragma once

#include <vector>

#include "millkit/driveline/scene.h"

namespace millkit::driveline {

// All N frequencies in Hz, ascending; the first is the rigid-body mode (0 to roundoff, clamped
// at 0). Assumes a valid scene (positive inertias and stiffnesses, a tree).
std::vector<double> NaturalFrequenciesHz(const driveline::Scene& scene);

// The lowest elastic natural frequency (Hz); 0 for a single mass.
double LowestNaturalFrequencyHz(const driveline::Scene& scene);

}  // namespace millkit::driveline
