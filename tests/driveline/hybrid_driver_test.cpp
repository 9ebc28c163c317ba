// The hybrid driver (src/driveline/hybrid_driver.h) on its own, with a scripted integrator: which
// legs it asks for, where it applies breakpoints and records, how it counts events and escapes a
// degenerate switch. And the solver registry every solver is listed in.
#include "driveline/hybrid_driver.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "millkit/driveline/simulation.h"
#include "scene_builder.h"

using namespace millkit::driveline;
using Catch::Matchers::Contains;

namespace {

// Moves straight to each leg's target, except at the scripted event times (each reported once,
// the first time a leg spans it); from `stall_at` to `stall_end`, every leg ends in an event
// `stall_advance` after its start (a stuck or chattering surface), unless the leg is blind to
// surfaces (an escape).
class ScriptedIntegrator final : public ModeIntegrator {
 public:
  std::vector<double> events;
  double stall_at = INFINITY, stall_end = INFINITY, stall_advance = 0.0;
  // What the driver asked for, in order.
  std::vector<Leg> legs;
  std::vector<std::pair<double, double>> breakpoints;  // (breakpoint, t)
  std::vector<std::pair<int, double>> records;         // (k, t) at each Record
  double t_now = 0.0;

  explicit ScriptedIntegrator(const Model& model) : model_(model) {}
  double time_scale() const override { return 1e-3; }
  std::string Start(const Eigen::VectorXd&, const Phases&, SimulationSummary*) override {
    return {};
  }
  void Advance(double t, const Leg& leg, LegEnd* end) override {
    legs.push_back(leg);
    end->crossed.assign(1, {0, 1});
    if (t >= stall_at && t < stall_end && leg.ignored == nullptr) {
      end->kind = LegEnd::Kind::kEvent;
      end->t = t + stall_advance;
      end->elapsed = stall_advance;
      t_now = end->t;
      return;
    }
    for (double& e : events) {
      if (e > t && e <= leg.target) {
        end->kind = LegEnd::Kind::kEvent;
        end->t = e;
        end->elapsed = e - t;
        e = -1.0;  // once
        t_now = end->t;
        return;
      }
    }
    end->kind = LegEnd::Kind::kReached;
    end->t = leg.target;
    end->elapsed = leg.target - t;
    t_now = end->t;
  }
  void EventMotion(Eigen::VectorXd* z, std::vector<Eigen::VectorXd>* derivatives) override {
    *z = model_.InitialState();
    derivatives->clear();
  }
  void Switch(const Phases&, double) override {}
  void ApplyBreakpoint(double breakpoint, double t) override {
    breakpoints.emplace_back(breakpoint, t);
  }
  void Record(OutputRecorder* recorder, int k, double t_output) override {
    records.emplace_back(k, t_now);
    CHECK(t_output == recorder->times()[k]);
    recorder->Record(k, model_.InitialPhases(), model_.InitialState());
  }
  void Finish(SimulationSummary* summary) override {
    summary->steps = static_cast<long>(legs.size());
  }

 private:
  const Model& model_;
};

Scene RampScene() {
  Scene scene = testing::TwoMassScene(1.0, 2.0, 1e4, 1.0, 0.01, 0.05, 1000.0);
  // A ramp from 2.5 ms to 4.0 ms (breakpoints between samples) and one from 6 ms to 6 ms + 1 ulp
  // of a sample time: the second is taken at the output time itself.
  scene.torques = {testing::Step(0, 0.0, 100.0, 0.0025, 0.0015),
                   testing::Step(1, 0.0, -50.0, 0.006, 0.0)};
  return scene;
}

}  // namespace

TEST_CASE(
    "hybrid driver: every output once in order, each breakpoint once before the outputs after it",
    "[driver]") {
  const Model model(RampScene());
  ScriptedIntegrator integrator(model);
  integrator.events = {0.0011, 0.0072};
  const SimulationOptions options;
  const SimulationResult result = RunHybrid(model, options, "scripted", &integrator);
  REQUIRE(result.summary.success);
  CHECK(result.summary.solver == "scripted");
  const int samples = model.scene().SampleCount();
  REQUIRE(static_cast<int>(integrator.records.size()) == samples);
  for (int k = 0; k < samples; ++k) {
    CHECK(integrator.records[k].first == k);
    CHECK(integrator.records[k].second == result.time_s[k]);
  }
  const std::vector<double> breakpoints = model.reduced_scene().InputBreakpoints();
  REQUIRE(integrator.breakpoints.size() == breakpoints.size());
  for (size_t b = 0; b < breakpoints.size(); ++b) {
    CHECK(integrator.breakpoints[b].first == breakpoints[b]);
    // Applied at the breakpoint itself, or at an output time within 4 ulps of it.
    CHECK(std::abs(integrator.breakpoints[b].second - breakpoints[b]) <=
          4 * std::numeric_limits<double>::epsilon() * breakpoints[b]);
  }
  CHECK(result.summary.events == 2);
  CHECK(result.summary.event_times_s == std::vector<double>{0.0011, 0.0072});
  // No leg runs past an output time or a breakpoint.
  for (const Leg& leg : integrator.legs) {
    CHECK(leg.target <= leg.output_time);
    if (leg.at_breakpoint) CHECK(leg.target <= leg.breakpoint * (1 + 1e-15));
  }
}

TEST_CASE("hybrid driver: max_events ends the run with the count and the time", "[driver]") {
  const Model model(RampScene());
  ScriptedIntegrator integrator(model);
  integrator.events = {0.001, 0.002, 0.003, 0.004};
  SimulationOptions options;
  options.max_events = 3;
  const SimulationResult result = RunHybrid(model, options, "scripted", &integrator);
  CHECK_FALSE(result.summary.success);
  CHECK(result.summary.events == 4);
  CHECK_THAT(result.summary.message, Contains("more than max_events = 3"));
}

TEST_CASE(
    "hybrid driver: a degenerate switch is escaped blind for 1e-9, 1e-6, 1e-3 of the time "
    "scale, then the run ends with a reason",
    "[driver]") {
  const Model model(RampScene());
  const double h = 1e-3;  // ScriptedIntegrator::time_scale
  SECTION("a surface that stays stuck: three escapes, then the reason") {
    ScriptedIntegrator integrator(model);
    integrator.stall_at = 0.0031;
    integrator.events = {0.0031};
    const SimulationResult result = RunHybrid(model, SimulationOptions{}, "scripted", &integrator);
    // The stall recurs after every escape (the scripted surface stays stuck), so all three
    // escapes are used and the run then ends.
    CHECK_FALSE(result.summary.success);
    CHECK_THAT(result.summary.message, Contains("events do not advance time"));
    std::vector<double> blind_targets;
    for (const Leg& leg : integrator.legs) {
      if (leg.ignored != nullptr && !leg.at_output && !leg.at_breakpoint) {
        blind_targets.push_back(leg.target);
      }
    }
    REQUIRE(blind_targets.size() == 3);
    CHECK(blind_targets[0] == Approx(0.0031 + 1e-9 * h).epsilon(1e-15));
    CHECK(blind_targets[1] == Approx(blind_targets[0] + 1e-6 * h).epsilon(1e-15));
    CHECK(blind_targets[2] == Approx(blind_targets[1] + 1e-3 * h).epsilon(1e-15));
    // 1 event to reach the surface, 65 stalled events before each escape, and 64 counted before
    // the one that ends the run.
    CHECK(result.summary.events == 1 + 3 * 65 + 64);
  }
  SECTION("events 1e-8 of the time scale apart are a degenerate switch too; 2e-6 apart are not") {
    // A contact chattering across a surface that both sides' motions point at (found by the
    // driveline fuzzer: a million events 4e-13 s apart, each above the ulps of t).
    ScriptedIntegrator chatter(model);
    chatter.stall_at = 0.0031;
    chatter.stall_advance = 1e-8 * h;
    chatter.events = {0.0031};
    const SimulationResult escaped = RunHybrid(model, SimulationOptions{}, "scripted", &chatter);
    CHECK_FALSE(escaped.summary.success);
    CHECK_THAT(escaped.summary.message, Contains("events do not advance time"));
    CHECK(escaped.summary.events == 1 + 3 * 65 + 64);
    ScriptedIntegrator slower(model);
    slower.stall_at = 0.0031;
    slower.stall_advance = 2e-6 * h;
    slower.events = {0.0031};
    SimulationOptions options;
    options.max_events = 1000;
    const SimulationResult counted = RunHybrid(model, options, "scripted", &slower);
    CHECK_FALSE(counted.summary.success);
    CHECK_THAT(counted.summary.message, Contains("more than max_events = 1000"));
  }
  SECTION("a stall that clears after one escape leaves a result") {
    ScriptedIntegrator integrator(model);
    integrator.stall_at = 0.0031;
    integrator.stall_end = 0.0031 + 0.5e-9 * h;  // before the first escape ends
    integrator.events = {0.0031};
    const SimulationResult result = RunHybrid(model, SimulationOptions{}, "scripted", &integrator);
    CHECK(result.summary.success);
    CHECK(result.summary.events == 1 + 65);
    CHECK(static_cast<int>(integrator.records.size()) == model.scene().SampleCount());
  }
}

TEST_CASE("solver registry: every solver by name, and each runs a scene under its name",
          "[driver]") {
  REQUIRE(Solvers().size() >= 2);
  for (const SolverInfo& info : Solvers()) {
    INFO(info.name);
    REQUIRE(FindSolver(info.name) == &SolverOf(info.kind));
    CHECK(std::string(info.description).size() > 10);
    CHECK_THAT(SolverNames(), Contains(info.name));
    SimulationOptions options;
    options.solver = info.kind;
    const SimulationResult result = Simulate(Model(RampScene()), options);
    CHECK(result.summary.success);
    CHECK(result.summary.solver == info.name);
    CHECK(result.summary.events > 0);
  }
  CHECK(FindSolver("euler") == nullptr);
  CHECK(FindSolver("") == nullptr);
  CHECK(std::string(SolverOf(SolverKind::kExact).name) == "exact");
  CHECK(std::string(SolverOf(SolverKind::kCvode).name) == "cvode");
}
