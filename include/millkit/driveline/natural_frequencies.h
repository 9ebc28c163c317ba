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

#include "millkit/driveline/model.h"
#include "millkit/driveline/scene.h"

namespace millkit::driveline {

// How a link with a gap counts in the stiffness matrix: its spring c (the coupling's catalogue
// stiffness), or the stiffest piece of its contact law (2c for `limited` links with b > 0: the
// fastest mode the solver can meet, for the sample-rate rule and the band reduction).
enum class GapStiffness { kSpring, kStiffestPiece };

// The one modal analysis of the drive line: undamped natural frequencies (Hz, ascending, the
// rigid-body mode first, clamped at 0) of `reduced` (a scene without gear ratios: ReducedScene)
// with the masses merged into the groups of `reduction` and its rigid links dropped, every gap
// closed. Solved as the symmetric eigenproblem J^-1/2 K J^-1/2. A c/J beyond the double range
// gives +inf frequencies, never a 0 that would pass a sample-rate rule.
std::vector<double> ModalFrequenciesHz(const Scene& reduced, const Reduction& reduction,
                                       GapStiffness gaps);

// All N frequencies in Hz, ascending; the first is the rigid-body mode (0 to roundoff, clamped
// at 0): ModalFrequenciesHz of the scene reduced to its reference shaft, no mass merged, every
// link with its spring c. Assumes a valid scene (positive inertias and stiffnesses, a tree).
std::vector<double> NaturalFrequenciesHz(const driveline::Scene& scene);

// The lowest elastic natural frequency (Hz); 0 for a single mass.
double LowestNaturalFrequencyHz(const driveline::Scene& scene);

}  // namespace millkit::driveline
