// Forward sensitivities of a simulation to named scene parameters (issue 15): the derivative of
// every link torque sample with respect to damping, stiffness, backlash, gap position, inertia,
// load and bite time (scene_parameter.h), computed alongside the exact solver's run.
//
// Within a phase set the augmented state obeys z' = M z, and the sensitivity s_j = ∂z/∂p_j obeys
//   s_j' = M s_j + M_j z,    M_j = ∂M/∂p_j,
// so over a leg of length τ from z(t):
//   s_j(t + τ) = exp(M τ) s_j(t) + F_j(τ) z(t),   [exp(Mτ) F_j; 0 exp(Mτ)] = exp([M M_j; 0 M] τ),
// the block-triangular exponential (cached per phase set for the sample step, a Taylor series or
// a matrix exponential on other legs). A recorder low-pass state (Link::recorder_lowpass_Hz),
// which no other state reads, is carried exactly beside the series of the others (its decay
// through their Taylor polynomial), so that a filter faster than the line does not shorten the
// series' pieces. At an event on surface g = G z whose right-hand side jumps
// (no_pull and linear contact laws; the limited law's is continuous there), with the event time's
// sensitivity ∂t_e/∂p_j = −(G s_j⁻ + G_j z) / (G f⁻):
//   s_j⁺ = s_j⁻ + (f⁻ − f⁺) ∂t_e/∂p_j,   f∓ = M∓ z.
// At an input breakpoint the forcing part of s_j takes the derivative of the forcing's right limit
// (−slope for the bite time, which shifts every breakpoint), and for the bite time the state part
// jumps by (z'⁻ − z'⁺). The link torques are T z per phase set, so their sensitivities are
// T s_j + T_j z.
// The model's coefficient derivatives M_j, G_j, T_j and ∂z(0)/∂p_j are taken from models built
// at neighbouring values (δ = 1e-3 of the parameter's magnitude). They are linear in every
// parameter but the inertias and stiffnesses, so one neighbour, p_j + δ (− δ at an upper
// bound), gives them to roundoff; those two (through 1/J and the static twists) take the
// fourth-order stencil at ± δ, ± 2δ (one-sided at a physical bound), whose error is ≈ 1e-12
// relative. Nothing is differenced through time or through the events.
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "millkit/driveline/scene_parameter.h"
#include "millkit/driveline/simulation.h"

namespace millkit::driveline {

struct SensitivityResult {
  SimulationResult simulation;  // the exact solver's run, as Simulate returns it
  // link_torque[j](k, i): ∂(torque of link i at output sample k)/∂(parameter j), in the
  // link's N·m per the parameter's unit; link i is the i-th of the links asked for (every
  // scene link, in order, by default). Empty when `unavailable` is set.
  std::vector<Eigen::MatrixXd> link_torque;
  // Why the sensitivities could not be computed, or empty: the run failed, it escaped a
  // degenerate switch, an event grazed its surface (the event sequence is not locally constant),
  // or a parameter's neighbours change the model's structure (a backlash of zero, a link made
  // rigid by the band). A caller then falls back to finite differences.
  std::string unavailable;
};

// Runs the exact solver on `scene` (options.solver is ignored; samples are kept, no sample sink)
// and the sensitivities of the link torques to `parameters`. Throws InputError for an invalid
// scene or options, as Simulate does.
// `links`: the scene links (indices) whose torques' sensitivities are recorded; empty: all. A
// fit asks for its channels' links only (the recording costs links × n × P per sample).
SensitivityResult SimulateWithSensitivities(const Scene& scene,
                                            const std::vector<SceneParameter>& parameters,
                                            const SimulationOptions& options,
                                            const std::vector<int>& links = {});

// An exact-solver run that keeps its stops (each leg's length and end state, each event,
// breakpoint and output time), so that the sensitivities to any scene parameters can follow it
// later without running the solver again: a fit evaluates its misfit at a trial point and, when
// it accepts the point, wants the misfit's derivatives there.
class RecordedRun {
 public:
  RecordedRun();  // holds no run
  // Runs `scene` with the exact solver as SimulateExact does (options.solver is ignored; the
  // samples are kept or streamed as the options say, and options.sample_sink and
  // options.progress are called during this run only). Throws InputError for an invalid scene or
  // options, as Simulate does. The stops are kept up to about `budget_bytes` (a state per stop:
  // the default holds some 100 000 stops of a 20-state model); a run that needs more (very many
  // events, a very long record) keeps none, and the sensitivities along it run the solver again.
  RecordedRun(const Scene& scene, const SimulationOptions& options,
              size_t budget_bytes = kDefaultBudgetBytes);
  static constexpr size_t kDefaultBudgetBytes = size_t{16} << 20;
  ~RecordedRun();
  RecordedRun(RecordedRun&&) noexcept;
  RecordedRun& operator=(RecordedRun&&) noexcept;

  bool empty() const { return kept_ == nullptr; }
  // Whether the run's stops were kept (false when they outgrew the budget).
  bool stops_kept() const;
  // The run's result (requires !empty()).
  const SimulationResult& result() const;

 private:
  struct Kept;
  std::unique_ptr<Kept> kept_;
  friend SensitivityResult SimulateWithSensitivities(const RecordedRun& run,
                                                     const std::vector<SceneParameter>& parameters,
                                                     const std::vector<int>& links);
};

// The sensitivities along a kept run (not empty), to the bit what SimulateWithSensitivities gives
// for the run's scene and options, without running the solver (unless its stops outgrew their
// budget): `simulation` is the run's result, whose samples are there only if the options kept
// them.
SensitivityResult SimulateWithSensitivities(const RecordedRun& run,
                                            const std::vector<SceneParameter>& parameters,
                                            const std::vector<int>& links = {});

}  // namespace millkit::driveline
