// The drive-line scene compiled for simulation (SPEC.md §2). Between switching events the model is
// the linear ODE x' = A x + B w with forcing w = [1, T_1(t), …, T_S(t)] linear in time between
// input breakpoints. Solvers work on the augmented state z = [x; w; w'] whose ODE z' = M z is
// autonomous, so z(t + τ) = exp(M τ) z(t) exactly (issue 2, exact solver).
//
// State x = [ψ of each flexible link, ω of each (merged) mass, (∫(ω_ref − ω) dt, M_drive),
// y of each link with a recorder low-pass (Link::recorder_lowpass_Hz: y' = a (m − y), a = 2π f_c,
// m the link's torque, linear in z within a phase set, so the filter stays inside z' = M z)].
// Only what a scene needs: links with b = 0 create no switching surfaces, a scene without a drive
// has no drive states, and with [scene] band the links whose mode lies far above the band are
// made rigid and their masses merged (SPEC §2.7).
//
// Switching surfaces are linear functionals g = G z; a backlash link has the six of its contact law
// (LinkSurfaceRows, backlash_law.h) over ψ, ψ' = ω_from − ω_to and the constant 1, with
// τc± = c(ψ ∓ b/2): S0 = ψ − b/2, S1 = ψ + b/2, S2 = τc+ + d ψ', S3 = d ψ' − τc+, S4 = τc− + d ψ',
// S5 = d ψ' − τc−; the model assembles G, the watched lists and the phases from the law's answers;
// for a drive: D0 = u − limit, D1 = u + limit with u = kp (ω_ref − ω) + ki ∫.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "millkit/driveline/backlash_law.h"
#include "millkit/driveline/scene.h"

namespace millkit::driveline {

// The drive's phase; a backlash link's is its LinkPhase, the region of its contact law
// (backlash_law.h).
enum class DrivePhase : std::uint8_t { kLinear, kSaturatedHigh, kSaturatedLow };

// One byte per backlash link, then one for the drive when there is one.
using Phases = std::string;

// What the band-limited reduction did.
struct Reduction {
  std::vector<int> group_of_mass;   // scene mass → merged mass (group)
  std::vector<bool> link_rigid;     // scene link → made rigid
  std::vector<std::string> report;  // one line per merge
};

// Makes rigid every link with b = 0 whose two-mass frequency sqrt(c (1/J_a + 1/J_b))/2π is at
// least kBandFactor × max(band, fastest mode of the model without it), highest first, merging
// masses as it goes. The second term keeps links whose mode an impact of a kept gap would excite.
// Identity without a band. `scene` has no gear ratios (ReducedScene; Model passes its own).
inline constexpr double kBandFactor = 10.0;
Reduction ReduceToBand(const Scene& scene);

// Highest natural frequency (Hz) of the reduced model with every backlash link in contact
// (stiffness 2c for `limited` links with b > 0, the stiffest piece of that law), undamped.
// `scene` has no gear ratios (ReducedScene).
double HighestModeHz(const Scene& scene, const Reduction& reduction);

// Throws InputError ([scene] sample_rate) when sample_rate < kSamplesPerFastestPeriod × the
// highest mode (after band reduction), found on ReducedScene(scene).
inline constexpr double kSamplesPerFastestPeriod = 4.0;
void CheckSampleRate(const Scene& scene);

// Quasi-static link torques (SPEC §2.5): the torque each link carries in the rigid-body motion
// under the given mass torques, m_s = J_B ε − Σ_B M with ε = ΣM / ΣJ and B the subtree on the
// link's `to` side. `mass_torques` includes any drive torque. `scene` has no gear ratios
// (ReducedScene), the torques are on the reference shaft.
std::vector<double> QuasiStaticLinkTorques(const Scene& scene,
                                           const std::vector<double>& mass_torques);

// External torque on each scene mass at time t (sources only, no drive).
std::vector<double> SourceTorquesAt(const Scene& scene, double t);

// The torque a speed drive holds at steady state: the net load, clipped to its limit (SPEC §2.5).
double SteadyDriveTorque(const Scene& scene, double t);

// Static torque of each scene link under the final loads (t = duration), used for Kd, in the
// link's own units (gear ratios allowed).
std::vector<double> StaticLinkTorques(const Scene& scene);

class Model {
 public:
  // What the model is built for: a run (the default), or only its coefficients (SystemMatrix,
  // surfaces, InitialState, LinkTorqueRows, SetForcing), as the stencil neighbours of a
  // sensitivity run are; such a model has no StateScale(), which only a run needs.
  enum class Use { kRun, kCoefficients };
  // Throws InputError for an invalid scene (ValidateScene).
  explicit Model(Scene scene, Use use = Use::kRun);

  // The scene as given (gear ratios and the units of each shaft).
  const Scene& scene() const { return user_scene_; }
  // The scene the model runs: every quantity on the reference shaft, no ratios (ReducedScene).
  // Solvers read inputs from it and convert outputs back with shaft_factors().
  const Scene& reduced_scene() const { return scene_; }
  const ShaftFactors& shaft_factors() const { return shaft_factors_; }
  const Reduction& reduction() const { return reduction_; }

  int state_size() const { return nx_; }    // x
  int forcing_size() const { return nw_; }  // w = [1, sources]
  int augmented_size() const { return nx_ + 2 * nw_; }
  int surface_count() const { return static_cast<int>(surfaces_.rows()); }
  int backlash_link_count() const { return static_cast<int>(backlash_links_.size()); }
  bool has_drive() const { return scene_.drive.has_value(); }
  int flexible_link_count() const { return static_cast<int>(flexible_links_.size()); }
  int group_count() const { return static_cast<int>(group_inertia_.size()); }

  // Augmented system matrix M (z' = M z) in the given phases.
  Eigen::MatrixXd SystemMatrix(const Phases& phases) const;
  // x' = A x + B w pieces of SystemMatrix (for CVODE).
  void LinearPieces(const Phases& phases, Eigen::MatrixXd* a, Eigen::MatrixXd* b) const;
  // G: one row per surface over z (slope columns are zero).
  const Eigen::MatrixXd& surfaces() const { return surfaces_; }
  // The surfaces whose crossing changes the phases (the others are not watched), each with the
  // sign (+1 or −1) it has on the side the phases describe.
  struct WatchedSurface {
    int index;
    int side;
  };
  std::vector<WatchedSurface> Watched(const Phases& phases) const;

  // The phases of state z. `known_sides` gives the side of surfaces the caller knows (the one
  // just crossed at an event: its new side). Any other surface whose value is zero to roundoff
  // takes its side from the sign of its first, then second, time derivative (zdot, zddot computed
  // in the phases before the event); with all three zero, the side without contact. The limited
  // law's S3 and S5 take the spring-damper side (kLinkSideFromMotion).
  struct KnownSide {
    int surface;
    int side;
  };
  Phases Classify(const Eigen::VectorXd& z, const Eigen::VectorXd& zdot,
                  const Eigen::VectorXd& zddot, const std::vector<KnownSide>& known_sides) const;
  // The same with the derivatives z', z'', z''', ... in `derivatives` (the first non-zero one
  // decides): a motion that starts at a higher order (a drive whose torque builds through its lag
  // from rest) leaves a surface on the side its first moving derivative shows.
  // With `before` (the phases the event ends), a backlash link that has no surface among
  // `known_sides` (the event does not involve it), on one of its surfaces that take the default
  // side (kLinkSideFromMotion false) to roundoff, keeps the side that surface bounds its region
  // in `before` on, where it bounds it: it has not crossed it. (Two links at the limited law's
  // corner at once, each on its S5 to roundoff, otherwise take the default side at the other's
  // event and swap regions at every event: random line 7697 under a speed-PI drive, at the bite.)
  Phases Classify(const Eigen::VectorXd& z, const std::vector<Eigen::VectorXd>& derivatives,
                  const std::vector<KnownSide>& known_sides, const Phases* before = nullptr) const;
  // Phases of the initial state (iterates Classify to a fixed point).
  Phases InitialPhases(const Eigen::VectorXd& z0) const;
  // InitialPhases(InitialState()), computed once.
  const Phases& InitialPhases() const { return initial_phases_; }
  // The phase sets that carry the most coupling: the initial ones, every backlash link in
  // contact, and every one dead (a drive linear in both). The state scale and the exact
  // solver's balancing read the system matrix over these.
  std::vector<Phases> CouplingPhaseSets() const;

  // Initial augmented state (SPEC §2.4): speeds initial.speed, quasi-static twists under the
  // loads at t = 0, gap_position·b/2 on links carrying no static torque, drive in steady state.
  Eigen::VectorXd InitialState() const { return initial_state_; }
  // Sets the forcing part of z (w and w') to the inputs at time t (right limit).
  void SetForcing(double t, Eigen::VectorXd* z) const;

  // Outputs per scene link and mass at state z in the given phases (SPEC §2.5). Rigid links report
  // the torque the rigid connection carries and its quasi-static twist m/c.
  // `system_matrix` (SystemMatrix(phases)) saves rebuilding it when links were made rigid.
  void Outputs(const Phases& phases, const Eigen::VectorXd& z, double* link_torque,
               double* mass_speed, double* link_twist,
               const Eigen::MatrixXd* system_matrix = nullptr) const;

  // The scene links' torques are linear in z (Outputs): link_torque = T z. Returns T (scene links
  // × augmented size) for the given phases; `system_matrix` is SystemMatrix(phases).
  Eigen::MatrixXd LinkTorqueRows(const Phases& phases, const Eigen::MatrixXd& system_matrix) const;

  // Typical magnitude of each x component (for absolute tolerances and error norms). Throws
  // std::logic_error on a model built for its coefficients only.
  Eigen::VectorXd StateScale() const;
  // Human-readable name of the phases, e.g. "upper_spindle:+sd lower_spindle:dead drive:lin".
  std::string DescribePhases(const Phases& phases) const;

  // Index of a scene link in the flexible-link list (−1 when rigid).
  int FlexibleIndexOf(int scene_link) const { return flexible_index_[scene_link]; }
  // Index in x of a scene link's recorder low-pass state (−1 without one).
  int FilterIndexOf(int scene_link) const { return filter_index_[scene_link]; }
  int TwistIndex(int flexible) const { return flexible; }
  int SpeedIndex(int group) const { return flexible_link_count() + group; }

 private:
  // Classify's rule for a link the event does not involve: the side `surface` bounds the link's
  // region in `before` on, when it bounds it (else false).
  bool KeptSide(int surface, const std::vector<KnownSide>& known_sides, const Phases& before,
                int* side) const;
  void BuildSurfaces();
  // The blocks A (state by state) and B (state by forcing) of SystemMatrix written into m, which
  // is augmented size square and zero on entry; the slope block is left zero.
  void StateAndInputBlocks(const Phases& phases, Eigen::MatrixXd* m) const;
  // Outputs and LinkTorqueRows with every link's own torque (no recorder low-pass).
  void OwnOutputs(const Phases& phases, const Eigen::VectorXd& z, double* link_torque,
                  double* mass_speed, double* link_twist,
                  const Eigen::MatrixXd* system_matrix) const;
  Eigen::MatrixXd OwnLinkTorqueRows(const Phases& phases,
                                    const Eigen::MatrixXd& system_matrix) const;
  // The initial state but its recorder low-pass states (zero), which SettleFilters then sets to
  // the filtered links' torques in initial_phases_.
  Eigen::VectorXd ComputeInitialState() const;
  void SettleFilters(Eigen::VectorXd* z) const;
  // After initial_state_ and initial_phases_.
  Eigen::VectorXd ComputeStateScale() const;
  // The torque coefficients of flexible link f in the given phases (the contact law's piece of a
  // backlash link, the plain spring-damper otherwise).
  LinkTorqueCoefficients FlexibleLinkCoefficients(const Phases& phases, int f) const;

  Scene user_scene_;  // as given
  Scene scene_;       // ReducedScene(user_scene_): what every member below works on
  ShaftFactors shaft_factors_;
  Reduction reduction_;
  int nx_ = 0;
  int drive_base_ = 0;   // x index of ∫(ω_ref − ω) dt; M_drive follows
  int filter_base_ = 0;  // x index of the first recorder low-pass state
  int nw_ = 0;
  std::vector<int> flexible_links_;        // scene link indices kept elastic
  std::vector<int> flexible_index_;        // scene link → flexible index or −1
  std::vector<int> filtered_links_;        // scene links with a recorder low-pass, in x order
  std::vector<int> filter_index_;          // scene link → x index of its low-pass state or −1
  std::vector<int> backlash_links_;        // flexible indices with b > 0
  std::vector<int> backlash_of_flexible_;  // flexible index → backlash index or −1
  std::vector<double> group_inertia_;
  Eigen::MatrixXd surfaces_;
  Eigen::MatrixXd abs_surfaces_;   // |surfaces_|, for roundoff scales
  std::vector<int> default_side_;  // side of each surface when it cannot be told
  // Per surface: on it to roundoff, the motion before the event decides its side (else the
  // default; kLinkSideFromMotion).
  std::vector<char> side_from_motion_;
  // For rigid links: the scene masses of the group on the link's `to` side.
  std::vector<std::vector<int>> rigid_to_side_masses_;
  Eigen::VectorXd initial_state_;  // InitialState(), computed once
  Eigen::VectorXd state_scale_;    // StateScale(), computed once
  Phases initial_phases_;          // InitialPhases(), computed once
};

}  // namespace millkit::driveline
