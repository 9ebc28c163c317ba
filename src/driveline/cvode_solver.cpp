// CVODES integrator for the drive line (issue 2). See simulation.h for the contract.
// Between events the model is x' = A x + B w(t) with w linear in time between input breakpoints;
// the Jacobian is A exactly. Root functions are the watched switching surfaces of the current
// phases; at a root the integrator stops, the hybrid driver (hybrid_driver.h) classifies the new
// phases (the crossed surface's new side is the root's direction) and CVODE is reinitialised.
// Input breakpoints are stop times; CVODE steps past an output time and interpolates back.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>
#include <exception>
#include <limits>
#include <unordered_map>

#include "driveline/hybrid_driver.h"
#include "millkit/driveline/simulation.h"
#include "numerics/sundials_handles.h"

namespace millkit::driveline {
namespace {

using numerics::CvodeMemory;
using numerics::SundialsContext;
using numerics::SundialsLinearSolver;
using numerics::SundialsMatrix;
using numerics::SundialsVector;

constexpr double kEps = std::numeric_limits<double>::epsilon();
// Root functions are the signed surfaces plus this fraction of their typical magnitude. CVODE
// deactivates a root function that is zero at the start of an integration and never reports a
// crossing of it afterwards: a link resting exactly on a flank (gap_position ±1) and pushed
// into contact would be missed. With the margin the function starts positive and the crossing
// is reported a roundoff-sized distance past the surface (the exact solver's kCrossingTolerance).
constexpr double kCrossingMargin = 1e-13;
// An output leg of more steps than this, whose last step is longer than kWedgeStep / |λ| for a
// lightly damped mode λ outside the current BDF order's stability wedge, caps the order
// (CapOrderWhereStable). An excited mode keeps the step near 0.05 / |λ| at rtol 1e-8 (order 5);
// one that has decayed lets it grow until the order's instability holds it near 0.6 / |λ|.
constexpr long kLegSteps = 1000;
constexpr double kWedgeStep = 0.3;

// Everything the C callbacks read. Callbacks are noexcept and report failure by return code.
struct Problem {
  const Model* model = nullptr;
  int nx = 0;
  Eigen::MatrixXd a, b;       // current phases
  Eigen::VectorXd w0, slope;  // forcing at t_segment and its slope
  double t_segment = 0.0;
  Eigen::MatrixXd rows;    // watched surfaces over [x; w], signed (>= 0 on the watched side)
  Eigen::VectorXd margin;  // per watched surface: kCrossingMargin × its typical magnitude
  std::vector<Model::WatchedSurface> watched;

  Eigen::VectorXd Forcing(double t) const { return w0 + slope * (t - t_segment); }
};

int Rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* user_data) noexcept {
  try {
    const auto& p = *static_cast<const Problem*>(user_data);
    Eigen::Map<const Eigen::VectorXd> x(N_VGetArrayPointer(y), p.nx);
    Eigen::Map<Eigen::VectorXd> xdot(N_VGetArrayPointer(ydot), p.nx);
    xdot.noalias() = p.a * x + p.b * p.Forcing(t);
    return 0;
  } catch (...) {
    return -1;
  }
}

int Jacobian(sunrealtype, N_Vector, N_Vector, SUNMatrix jac, void* user_data, N_Vector, N_Vector,
             N_Vector) noexcept {
  const auto& p = *static_cast<const Problem*>(user_data);
  for (int j = 0; j < p.nx; ++j) {
    sunrealtype* column = SUNDenseMatrix_Column(jac, j);
    for (int i = 0; i < p.nx; ++i) column[i] = p.a(i, j);
  }
  return 0;
}

int Roots(sunrealtype t, N_Vector y, sunrealtype* g, void* user_data) noexcept {
  try {
    const auto& p = *static_cast<const Problem*>(user_data);
    Eigen::Map<const Eigen::VectorXd> x(N_VGetArrayPointer(y), p.nx);
    const Eigen::VectorXd w = p.Forcing(t);
    for (int i = 0; i < static_cast<int>(p.watched.size()); ++i) {
      g[i] = p.rows.row(i).head(p.nx).dot(x) + p.rows.row(i).tail(w.size()).dot(w) + p.margin[i];
    }
    return 0;
  } catch (...) {
    return -1;
  }
}

std::string FlagName(int flag) {
  char* name = CVodeGetReturnFlagName(flag);
  std::string text = name != nullptr ? name : std::to_string(flag);
  free(name);  // CVodeGetReturnFlagName allocates with malloc
  return text;
}

void Check(int flag, const char* call) {
  if (flag < 0) throw std::runtime_error(std::string(call) + " failed: " + FlagName(flag));
}

class CvodeIntegrator final : public ModeIntegrator {
 public:
  CvodeIntegrator(const Model& model, const SimulationOptions& options)
      : model_(model),
        options_(options),
        nx_(model.state_size()),
        nw_(model.forcing_size()),
        h_(1.0 / model.reduced_scene().sample_rate_Hz) {}

  double time_scale() const override { return h_; }

  std::string Start(const Eigen::VectorXd& z0, const Phases& phases,
                    SimulationSummary* summary) override {
    summary->error_kind = "requested tolerance";
    summary->error_estimate = options_.rtol;
    problem_.model = &model_;
    problem_.nx = nx_;
    problem_.w0 = z0.segment(nx_, nw_);
    problem_.slope = z0.tail(nw_);
    state_scale_ = model_.StateScale();
    phases_ = phases;
    Configure();
    try {
      y_ = SundialsVector(N_VNew_Serial(nx_, context_.get()));
      SundialsVector atol(N_VNew_Serial(nx_, context_.get()));
      CvodeState() = z0.head(nx_);
      Eigen::Map<Eigen::VectorXd>(N_VGetArrayPointer(atol.get()), nx_) =
          options_.atol.value_or(options_.rtol) * state_scale_;
      jacobian_ = SundialsMatrix(SUNDenseMatrix(nx_, nx_, context_.get()));
      solver_ = SundialsLinearSolver(SUNLinSol_Dense(y_.get(), jacobian_.get(), context_.get()));
      memory_ = CvodeMemory(CVodeCreate(CV_BDF, context_.get()));
      void* mem = memory_.get();
      Check(CVodeInit(mem, Rhs, 0.0, y_.get()), "CVodeInit");
      Check(CVodeSVtolerances(mem, options_.rtol, atol.get()), "CVodeSVtolerances");
      Check(CVodeSetUserData(mem, &problem_), "CVodeSetUserData");
      Check(CVodeSetLinearSolver(mem, solver_.get(), jacobian_.get()), "CVodeSetLinearSolver");
      Check(CVodeSetJacFn(mem, Jacobian), "CVodeSetJacFn");
      Check(CVodeSetMaxNumSteps(mem, options_.max_steps), "CVodeSetMaxNumSteps");
      Check(CVodeSetNoInactiveRootWarn(mem), "CVodeSetNoInactiveRootWarn");
      SetRoots();
    } catch (const std::exception& e) {
      return e.what();
    }
    return {};
  }

  void Advance(double t, const Leg& leg, LegEnd* end) override {
    end->kind = LegEnd::Kind::kReached;
    end->t = t;
    end->elapsed = 0.0;
    if (!failure_.empty()) return Fail(failure_, end);
    try {
      if (Ignoring(leg.ignored)) {
        ignored_ = leg.ignored != nullptr ? *leg.ignored : std::vector<char>{};
        Configure();
        Restart(t);
      }
      const double tout = leg.output_time;
      if (leg.at_output && tout - t <= 4 * kEps * std::max(1.0, tout)) {
        return;  // an event or a breakpoint landed on this output time: the state is there
      }
      // Output times are interpolated; breakpoints, the end of the run and an escape's end are
      // stops.
      const double stop = leg.at_breakpoint ? leg.breakpoint
                          : leg.at_output   ? leg.next_stop
                                            : leg.target;
      if (stop != stop_) {
        Check(CVodeSetStopTime(memory_.get(), stop), "CVodeSetStopTime");
        stop_ = stop;
      }
      double reached = t;
      long steps_before = 0;
      CVodeGetNumSteps(memory_.get(), &steps_before);
      const int flag = CVode(memory_.get(), tout, y_.get(), &reached, CV_NORMAL);
      t_ = reached;
      if (flag >= 0 && flag != CV_ROOT_RETURN) CapOrderWhereStable(steps_before);
      end->t = reached;
      end->elapsed = reached - t;
      if (flag == CV_ROOT_RETURN) {
        roots_found_.assign(problem_.watched.size(), 0);
        Check(CVodeGetRootInfo(memory_.get(), roots_found_.data()), "CVodeGetRootInfo");
        end->kind = LegEnd::Kind::kEvent;
        end->crossed.clear();
        for (size_t i = 0; i < roots_found_.size(); ++i) {
          // The signed function falls through zero: the surface's new side is −side.
          if (roots_found_[i] != 0) {
            end->crossed.push_back(
                {problem_.watched[i].index, roots_found_[i] * problem_.watched[i].side});
          }
        }
        return;
      }
      if (flag < 0) {
        return Fail("CVode failed at t = " + std::to_string(reached) + ": " + FlagName(flag), end);
      }
      if (flag != CV_TSTOP_RETURN && !CvodeState().allFinite()) {
        return Fail("state became non-finite at t = " + std::to_string(reached), end);
      }
    } catch (const std::exception& e) {
      Fail(e.what(), end);
    }
  }

  void EventMotion(Eigen::VectorXd* z, std::vector<Eigen::VectorXd>* derivatives) override {
    *z = Augmented(t_);
    const Eigen::MatrixXd m = model_.SystemMatrix(phases_);
    derivatives->resize(2);
    (*derivatives)[0] = m * *z;
    (*derivatives)[1] = m * (*derivatives)[0];
  }

  void Switch(const Phases& phases, double t) override {
    phases_ = phases;
    max_order_ = 5;
    Configure();
    Restart(t);
  }

  void ApplyBreakpoint(double breakpoint, double t) override {
    const Scene& scene = model_.reduced_scene();
    for (int s = 0; s < nw_ - 1; ++s) {
      problem_.w0[1 + s] = scene.torques[s].ValueAt(breakpoint);
      problem_.slope[1 + s] = scene.torques[s].SlopeAt(breakpoint);
    }
    problem_.t_segment = t;
    max_order_ = 5;  // an input's kink may excite the mode again
    Restart(t);
  }

  void Record(OutputRecorder* recorder, int k, double t_output) override {
    recorder->Record(k, phases_, Augmented(t_output));
  }

  void Finish(SimulationSummary* summary) override {
    if (summary->message.empty() && !failure_.empty()) summary->message = failure_;
    Harvest();
    summary->steps = steps_;
    summary->rhs_evaluations = rhs_;
    summary->jacobian_evaluations = jacobians_;
  }

 private:
  // The state x as CVODE holds it (named apart from ModeIntegrator::State, the observer's copy).
  Eigen::Map<Eigen::VectorXd> CvodeState() { return {N_VGetArrayPointer(y_.get()), nx_}; }
  // [x; w; w'] at time t.
  Eigen::VectorXd Augmented(double t) {
    Eigen::VectorXd z(model_.augmented_size());
    z << CvodeState(), problem_.Forcing(t), problem_.slope;
    return z;
  }
  void Fail(const std::string& message, LegEnd* end) {
    end->kind = LegEnd::Kind::kFailed;
    end->message = message;
  }
  // Whether the set of ignored surfaces differs from the one in use.
  bool Ignoring(const std::vector<char>* ignored) const {
    if (ignored == nullptr) return !ignored_.empty();
    return ignored_ != *ignored;
  }
  // The root functions of the current phases (less the ignored surfaces).
  void Configure() {
    model_.LinearPieces(phases_, &problem_.a, &problem_.b);
    problem_.watched = model_.Watched(phases_);
    if (!ignored_.empty()) {
      std::erase_if(problem_.watched,
                    [&](const Model::WatchedSurface& w) { return ignored_[w.index] != 0; });
    }
    const int count = static_cast<int>(problem_.watched.size());
    problem_.rows.resize(count, nx_ + nw_);
    problem_.margin.resize(count);
    for (int r = 0; r < count; ++r) {
      const Model::WatchedSurface& w = problem_.watched[r];
      problem_.rows.row(r) = w.side * model_.surfaces().row(w.index).head(nx_ + nw_);
      problem_.margin[r] =
          kCrossingMargin *
          (problem_.rows.row(r).head(nx_).cwiseAbs().dot(state_scale_) +
           problem_.rows.row(r).tail(nw_).cwiseAbs().dot(problem_.w0.cwiseAbs().cwiseMax(1.0)));
    }
  }
  // Lightly damped fast modes of the current phases: |λ| and the highest BDF order whose
  // stability wedge holds λ (orders 3, 4, 5 are A(α)-stable for α = 86.03°, 73.35°, 51.84°;
  // 1 and 2 A-stable), for the modes that order 5 cannot take.
  struct WedgeMode {
    double rate;
    int order;
  };
  const std::vector<WedgeMode>& WedgeModes() {
    auto found = wedge_modes_.find(phases_);
    if (found != wedge_modes_.end()) return found->second;
    std::vector<WedgeMode> modes;
    Eigen::EigenSolver<Eigen::MatrixXd> solver(problem_.a, false);
    if (solver.info() == Eigen::Success) {
      constexpr double kWedge[6] = {0, 90, 90, 86.03, 73.35, 51.84};
      for (const std::complex<double>& lambda : solver.eigenvalues()) {
        if (!(lambda.real() < 0.0)) continue;
        const double angle = std::atan2(std::abs(lambda.imag()), -lambda.real()) * 180.0 / M_PI;
        int order = 5;
        while (order > 2 && angle > kWedge[order]) --order;
        if (order < 5) modes.push_back({std::abs(lambda), order});
      }
    }
    return wedge_modes_.emplace(phases_, std::move(modes)).first->second;
  }
  // After a leg of many steps: where CVODE's step has grown past a lightly damped fast mode
  // (h |λ| > kWedgeStep) that its order cannot damp, the order is capped until the next switch
  // or input breakpoint. Such a mode has decayed (an excited one keeps the step far
  // below), and the higher orders' instability on it would hold the step there for the run.
  void CapOrderWhereStable(long steps_before) {
    long steps = 0;
    double h = 0.0;
    CVodeGetNumSteps(memory_.get(), &steps);
    if (steps - steps_before < kLegSteps) return;
    CVodeGetLastStep(memory_.get(), &h);
    int cap = max_order_;
    for (const WedgeMode& mode : WedgeModes()) {
      if (h * mode.rate > kWedgeStep) cap = std::min(cap, mode.order);
    }
    if (cap < max_order_) {
      max_order_ = cap;
      // From order 1 under the new cap, at the output time just reached: lowering the cap in the
      // middle of CVODE's history left it stepping by 1e-19 s.
      Restart(t_);
    }
  }
  void SetRoots() {
    Check(CVodeSetMaxOrd(memory_.get(), max_order_), "CVodeSetMaxOrd");
    Check(CVodeRootInit(memory_.get(), static_cast<int>(problem_.watched.size()),
                        problem_.watched.empty() ? nullptr : Roots),
          "CVodeRootInit");
  }
  // Restarts CVODE at t from the current state (after a switch, a breakpoint, an escape); a
  // failure ends the run at the next leg.
  void Restart(double t) {
    try {
      Harvest();
      Check(CVodeReInit(memory_.get(), t, y_.get()), "CVodeReInit");
      SetRoots();
      stop_ = std::numeric_limits<double>::quiet_NaN();  // set again before the next step
      t_ = t;
    } catch (const std::exception& e) {
      if (failure_.empty()) failure_ = e.what();
    }
  }
  // Adds the counters of the current CVODE run (since the last restart) to the totals.
  void Harvest() {
    void* mem = memory_.get();
    if (mem == nullptr) return;
    long value = 0;
    CVodeGetNumSteps(mem, &value);
    steps_ += value;
    CVodeGetNumRhsEvals(mem, &value);
    rhs_ += value;
    CVodeGetNumJacEvals(mem, &value);
    jacobians_ += value;
  }

  const Model& model_;
  const SimulationOptions& options_;
  const int nx_, nw_;
  const double h_;
  Problem problem_;
  Eigen::VectorXd state_scale_;
  Phases phases_;
  std::vector<char> ignored_;  // empty: every watched surface is a root function
  SundialsContext context_;
  SundialsVector y_;
  SundialsMatrix jacobian_;
  SundialsLinearSolver solver_;
  CvodeMemory memory_;
  double t_ = 0.0;  // CVODE's time
  double stop_ = std::numeric_limits<double>::quiet_NaN();
  std::vector<int> roots_found_;
  std::unordered_map<Phases, std::vector<WedgeMode>> wedge_modes_;
  int max_order_ = 5;
  std::string failure_;  // from a restart
  long steps_ = 0, rhs_ = 0, jacobians_ = 0;
};

}  // namespace

std::unique_ptr<ModeIntegrator> MakeCvodeIntegrator(const Model& model,
                                                    const SimulationOptions& options) {
  return std::make_unique<CvodeIntegrator>(model, options);
}

}  // namespace millkit::driveline
