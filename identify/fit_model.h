// The model evaluation of a fit (identify/ internal): the fitted quantities, the simulation of
// every record, the residuals and their finite-difference Jacobians.
//
// Over R records (one simulation of the scene per record) the fitted quantities are
//   θ = [u_1 … u_S, g_1, ô_1, …, g_B, ô_B].
// Slot s is a free parameter, shared by every record or, for a per-record parameter (bite time),
// one copy per record, in its unit coordinate u_s (identify/parameter_map.h). Block b is one
// channel of one record, with its own gain g_b and offset ô_b = o_b / S_b (S_b the block's peak
// |y|, for conditioning). Residuals are the blocks' window samples, block after block, each
// weighted by its fixed weight w_b = 1/σ_b (identify/record_noise.h) unless the config gives one.
//
// Variable projection: while iterating, gains and offsets are not Ceres parameters. For given
// scene parameters they are solved in closed form (least squares within their bounds), and the
// residual is that projected one; its finite differences carry the nuisance's response. Only the
// covariance uses the full θ (FullJacobian).
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <atomic>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "identify/parameter_map.h"
#include "millkit/driveline/scene.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"
#include "numerics/parallel_for.h"

namespace millkit::identify {

struct Nuisance {
  double gain = 1.0;
  double offset_Nm = 0.0;
  bool gain_at_bound = false;
  bool offset_at_bound = false;
};

class FitModel {
 public:
  struct Slot {
    int free = 0;     // index in config.free
    int record = -1;  // −1: shared by every record
    std::string name;
    ParameterMap map;
  };
  struct Block {
    int record = 0;
    int channel = 0;  // index in config.channels
    int column = 0;   // index in the record's channels
    int begin = 0;    // window samples [begin, end) of the record at this stage
    int end = 0;
    int full_end = 0;
    double scale = 1.0;  // peak |y| over the window
    double weight = 1.0;
    double gain_lower = 0.0, gain_upper = 0.0;
    double offset_lower_Nm = 0.0, offset_upper_Nm = 0.0;
    Eigen::VectorXd measured;
    int offset = 0;  // first residual of the block
  };

  // weights: one per block (record by record, channels in config order).
  FitModel(const driveline::Scene& scene, const std::vector<Oscillogram>& records,
           const FitConfig& config, const std::vector<double>& weights);

  // Continuation over the window length: each record's window ends at onset + (end − onset)/d
  // (d = 1: the whole window).
  void SetStage(double divisor);
  int FewestSamples(double divisor) const;

  int parameters() const { return static_cast<int>(slots_.size()); }
  int blocks() const { return static_cast<int>(blocks_.size()); }
  int size() const { return parameters() + 2 * blocks(); }
  int gain_index(int b) const { return parameters() + 2 * b; }
  int offset_index(int b) const { return parameters() + 2 * b + 1; }
  int residuals() const { return residuals_; }
  const Block& block(int b) const { return blocks_[b]; }
  const Slot& slot(int s) const { return slots_[s]; }
  const FreeParameter& free(int s) const { return config_.free[slots_[s].free]; }
  const ChannelSpec& channel_spec(int b) const { return config_.channels[blocks_[b].channel]; }
  const Oscillogram& record(int r) const { return records_[r]; }
  const std::string& label(int r) const { return labels_[r]; }
  // Simulations so far, by this model and every copy of it (the count is shared).
  long simulations() const { return *simulations_; }
  // What the fit is doing, for the progress callback (called after every simulation, by this
  // model and its copies, one call at a time).
  void set_progress(std::function<void(const std::string&, long)> progress) {
    progress_ = std::move(progress);
  }
  void set_activity(std::string activity) const { activity_ = std::move(activity); }
  // Why the latest simulation that failed failed (a copy keeps its own).
  const std::string& last_failure() const { return last_failure_; }
  void set_last_failure(std::string why) const { last_failure_ = std::move(why); }

  double Physical(int s, double u) const { return slots_[s].map.Physical(u); }
  double Unit(int s, double value) const { return slots_[s].map.Unit(value); }
  // The quantities of θ held constant (gains or offsets the config does not fit), and the others.
  std::vector<int> ConstantIndices() const;
  std::vector<int> FittedIndices() const;
  // Gain.<column> or offset.<column>, with @<record label> when there are several records.
  std::string NuisanceName(int b, bool gain) const;

  // Simulated link torque of every block for scene parameters u (unit coordinates); with
  // `only_record` ≥ 0 only that record's blocks are simulated (the others are left as they are).
  // With `kept`, each record's exact-solver run is kept there (kept[r]) for DerivativesAlong.
  bool Torques(const double* u, std::vector<Eigen::VectorXd>* m, int only_record = -1,
               std::vector<driveline::RecordedRun>* kept = nullptr) const;
  // Torques as Torques does, with their derivatives over the unit coordinates: dm[b] is block b's
  // samples × parameters() (zero columns for slots of other records and for `frozen` slots, which
  // are not computed). False when a simulation fails; *available false (dm unset) when the
  // sensitivities cannot be computed at u.
  bool TorquesWithDerivatives(const double* u, std::vector<Eigen::VectorXd>* m,
                              std::vector<Eigen::MatrixXd>* dm, bool* available,
                              const std::vector<int>& frozen = {}) const;
  // The derivatives TorquesWithDerivatives gives, along the runs `kept` by Torques at the same u
  // (every record's), without running the solver again.
  bool DerivativesAlong(const std::vector<driveline::RecordedRun>& kept, const double* u,
                        std::vector<Eigen::MatrixXd>* dm, bool* available,
                        const std::vector<int>& frozen = {}) const;
  // The derivative of block b's projected residual w_b (g m + o − y) over the scene parameters,
  // the gain and offset following m (solved again: their change where they are inside their
  // bounds), for torque m with derivatives dm (samples × parameters) and its solution n.
  Eigen::MatrixXd ProjectedDerivative(int b, const Eigen::VectorXd& m, const Eigen::MatrixXd& dm,
                                      const Nuisance& n) const;
  // The gain and offset that minimise block b's misfit for torque m, within their bounds.
  Nuisance SolveNuisance(int b, const Eigen::VectorXd& m) const;
  // Weighted residuals w_b (g_b m_b + o_b − y_b) of block b into r (its own rows).
  void BlockResiduals(int b, const Eigen::VectorXd& m, const Nuisance& n, double* r) const;
  // Residuals of every block for torques m with the nuisance solved; false when not finite.
  bool Project(const std::vector<Eigen::VectorXd>& m, Eigen::VectorXd* r,
               std::vector<Nuisance>* nuisance = nullptr) const;
  // Projected residuals of every block (nuisance solved); false when a simulation fails.
  bool ProjectedResiduals(const double* u, Eigen::VectorXd* r,
                          std::vector<Nuisance>* nuisance = nullptr,
                          std::vector<Eigen::VectorXd>* m = nullptr) const;
  // ½ Σ r² of the projected residuals; +inf when a simulation fails.
  double ProjectedCost(const double* u) const;

  // Jacobian of the full (unprojected) residual over θ at u and the nuisance, analytic in the
  // gains and offsets. The scene parameters' columns: with Derivatives::kSensitivity from the
  // exact solver's sensitivities where they are available, else (and for the other kinds) by
  // central differences (second-order one-sided at a bound) with normalised step h. False when a
  // simulation fails.
  bool FullJacobian(const std::vector<double>& u, const std::vector<Nuisance>& nuisance,
                    double step, Derivatives derivatives, Eigen::VectorXd* r,
                    Eigen::MatrixXd* jacobian) const;

 private:
  // Record r's scene at u; with `parameters`, also the scene parameters of its slots that are not
  // `frozen`, and the slot of each.
  driveline::Scene RecordScene(int r, const double* u, const std::vector<int>& frozen,
                               std::vector<driveline::SceneParameter>* parameters,
                               std::vector<int>* slots) const;
  // One more simulation: the count, and the progress callback.
  void CountSimulation() const;
  // Record r's channel derivatives over its scene parameters (those of `slots`) into dm, over the
  // unit coordinates.
  void ToUnits(int r, const double* u, const std::vector<int>& slots,
               const std::vector<Eigen::MatrixXd>& derivatives,
               std::vector<Eigen::MatrixXd>* dm) const;
  int StageEnd(const Block& b, double divisor) const;
  // FullJacobian computed (it looks up the last one first).
  bool FullJacobianAnew(const std::vector<double>& u, const std::vector<Nuisance>& nuisance,
                        double step, Derivatives derivatives, Eigen::VectorXd* r,
                        Eigen::MatrixXd* jacobian) const;
  double OnsetTime(int r) const;

  const driveline::Scene& scene_;
  const std::vector<Oscillogram>& records_;
  const FitConfig& config_;
  std::vector<std::string> labels_;
  std::vector<Slot> slots_;
  std::vector<Block> blocks_;
  std::vector<double> onsets_;
  int residuals_ = 0;
  // Copies of a model (the workers of a parallel search, identify/multistart.cpp) share the
  // simulation count and call the progress callback under one lock.
  std::shared_ptr<std::atomic<long>> simulations_ = std::make_shared<std::atomic<long>>(0);
  std::shared_ptr<std::mutex> progress_mutex_ = std::make_shared<std::mutex>();
  std::function<void(const std::string&, long)> progress_;
  mutable std::string activity_ = "starting";
  mutable std::string last_failure_;
  // The last FullJacobian, its arguments and results: the search asks for it at the best minimum
  // for the basin hops, the curved valleys and the report, usually at the same point (the
  // same bits as computing it again: the model keeps no other state that it reads). Not
  // copied: a worker's copy starts without it.
  struct JacobianMemo {
    JacobianMemo() = default;
    JacobianMemo(const JacobianMemo&) {}
    JacobianMemo& operator=(const JacobianMemo&) {
      valid = false;
      return *this;
    }
    bool Matches(const std::vector<double>& at, const std::vector<Nuisance>& with, double h,
                 Derivatives kind) const;
    bool valid = false;
    std::vector<double> u;
    std::vector<Nuisance> nuisance;
    double step = 0.0;
    Derivatives derivatives = Derivatives::kSensitivity;
    Eigen::VectorXd r;
    Eigen::MatrixXd jacobian;
  };
  mutable JacobianMemo jacobian_memo_;
};

// The projected misfit as one Ceres residual block over the angles φ of the scene parameters.
// Jacobian by finite differences in u (forward, or central), or from the forward sensitivities
// (FitOptions::derivatives), chained with du/dφ; a per-record slot re-simulates only
// its record. Frozen slots keep a zero column, unsimulated. Where the sensitivities are not
// available the evaluation takes forward differences.
class ProjectedResidual : public ceres::CostFunction {
 public:
  ProjectedResidual(const FitModel& model, double step, Derivatives derivatives,
                    std::vector<int> frozen = {});
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  // Once asked to (a pivoted QR of every Jacobian, for FitOptions' statistical stop): at the
  // point of the latest evaluation with a Jacobian (Levenberg–Marquardt's current point), the
  // length of the Gauss–Newton step from it, in standard errors; NaN before the first Jacobian,
  // when not asked, or when the residuals leave no degree of freedom.
  void MeasureRemainingStep() { measure_step_ = true; }
  double remaining_step_se() const { return remaining_step_se_; }
  // Also once asked to: the Gram matrix JᵀJ / s² at that point (φ coordinates; empty before the
  // first Jacobian or without a degree of freedom), the inverse of the covariance there.
  const Eigen::MatrixXd& precision() const { return precision_; }
  // The angles φ of the latest evaluation with a Jacobian (empty before the first).
  const std::vector<double>& jacobian_point() const { return jacobian_point_; }

  // Levenberg–Marquardt evaluates the Jacobian at every point it accepts before it asks its
  // callbacks and its iteration cap whether to go on. Where it stops right there, that Jacobian
  // is never read: at the cap (`last_iteration`, Ceres' max_num_iterations) of a refinement that
  // keeps no precision (MeasureRemainingStep not asked), or at an accepted point that `stop`
  // (given its φ and cost ½‖r‖²) ends the fit at. That Jacobian is then skipped (with
  // sensitivities it would follow the plain run just before; with differences, the residuals
  // are run again and the P probes spared): the residuals come with a zero Jacobian.
  // An IterationCallback must report each finished iteration (IterationFinished) and end the
  // fit once stopped(); jacobian_skipped() tells that the latest Jacobian was not computed
  // (jacobian_point() is then an earlier point's).
  void EndEarly(int last_iteration, std::function<bool(const double* phi, double cost)> stop) {
    last_iteration_ = last_iteration;
    stop_ = std::move(stop);
  }
  void IterationFinished(int iteration) const { iteration_ = iteration + 1; }
  bool stopped() const { return stopped_; }
  bool jacobian_skipped() const { return jacobian_skipped_; }

 private:
  const FitModel& model_;
  double step_;
  Derivatives derivatives_;
  std::vector<int> frozen_;
  bool measure_step_ = false;
  mutable double remaining_step_se_ = std::numeric_limits<double>::quiet_NaN();
  mutable Eigen::MatrixXd precision_;
  mutable std::vector<double> jacobian_point_;
  int last_iteration_ = std::numeric_limits<int>::max();
  std::function<bool(const double*, double)> stop_;
  mutable int iteration_ = 0;  // the iteration in progress
  mutable bool stopped_ = false;
  mutable bool jacobian_skipped_ = false;
  // Where the Jacobian at φ (residuals r) would never be read (EndEarly): writes r and a zero
  // Jacobian and returns true.
  bool SkipJacobian(const double* phi, const Eigen::VectorXd& r, double* residuals,
                    double* jacobian) const;
  // With sensitivities, the latest plain evaluation (not yet followed by a Jacobian there): its
  // point φ, torques, residuals and each record's run, which the Jacobian that
  // Levenberg–Marquardt asks for after accepting that point follows instead of running again.
  mutable std::vector<double> kept_point_;
  mutable std::vector<Eigen::VectorXd> kept_m_;
  mutable Eigen::VectorXd kept_r_;
  mutable std::vector<driveline::RecordedRun> kept_runs_;
  void Measure(const Eigen::Ref<const Eigen::MatrixXd>& jacobian, const Eigen::VectorXd& residuals,
               const double* phi) const;
};

// The Gauss–Newton step −J⁺r in standard errors: √(‖Q₁ᵀr‖² / s²), Q₁ spanning J's numerical
// column space (pivoted QR), s² = (‖r‖² − ‖Q₁ᵀr‖²) / (n − rank). NaN without a degree of freedom
// or when J has no column of rank.
double GaussNewtonStepInStandardErrors(const Eigen::Ref<const Eigen::MatrixXd>& jacobian,
                                       const Eigen::VectorXd& residuals,
                                       double* variance = nullptr);

// Runs task(worker_model, i) for every i in [0, count) on `threads` workers, each with its
// own copy of `model` (its own stage; the simulation count and progress are shared), and returns
// the results in index order: the same for any thread count. The model's last failure becomes
// that of the highest index that had one, as a serial loop would leave it.
template <typename Result, typename Task>
std::vector<Result> MapOverCopies(const FitModel& model, int threads, int count, const Task& task) {
  std::vector<Result> results(count);
  std::vector<std::string> failures(count);
  const int workers = std::clamp(threads, 1, std::max(count, 1));
  std::vector<FitModel> copies(workers, model);
  numerics::ParallelFor(count, workers, [&](int i, int worker) {
    FitModel& copy = copies[worker];
    copy.set_last_failure({});
    results[i] = task(copy, i);
    failures[i] = copy.last_failure();
  });
  for (auto& failure : failures) {
    if (!failure.empty()) model.set_last_failure(std::move(failure));
  }
  return results;
}

}  // namespace millkit::identify
