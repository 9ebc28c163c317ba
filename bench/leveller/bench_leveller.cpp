// Leveller inverse kinematics: setpoints per second against error, for the closed form and each
// NLopt formulation/algorithm tried (issue 4). Not a test: it prints a table, checks its own
// answers through the forward map, and exits 1 if the closed form or the default NLopt method
// (SLSQP, equality-constrained) misses a target by more than 1e-9 mm or rejects one.
//
//   bench_leveller [targets]   (default 20000; the closed form runs 10x as many)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "millkit/leveller/linkage.h"
#include "millkit/optimize/leveller/nlopt_inverse.h"

namespace {

using namespace millkit::leveller;
using millkit::optimize::Algorithm;

constexpr double kToleranceMm = 1e-9;
constexpr double kClosedFormTargetPerS = 1e6;
constexpr double kNloptTargetPerS = 1e4;

struct Target {
  double beta1, beta2, y1, y2;
};

struct Row {
  std::string method;
  int solves = 0;
  double per_second = 0.0;
  double max_error_mm = 0.0;
  double max_beta_error_deg = 0.0;  // against the generating angles, |β| ≤ 89° only
  int rejected = 0;
};

std::vector<Target> MakeTargets(const Linkage& linkage, int count) {
  std::mt19937 random(20240404);  // seeded: the same targets every run
  // Principal branch of the working range: above the lower dead centre (about -89.98 deg).
  std::uniform_real_distribution<double> beta(-89.95, 90.0);
  std::vector<Target> targets;
  targets.reserve(count);
  while (static_cast<int>(targets.size()) < count) {
    const double b1 = beta(random);
    const double b2 = beta(random);
    Intermesh<double> y;
    if (!linkage.Forward(b1, b2, &y)) continue;
    targets.push_back({b1, b2, y.y1, y.y2});
  }
  return targets;
}

template <typename Solve>
Row Measure(const std::string& method, const Linkage& linkage, const std::vector<Target>& targets,
            Solve solve) {
  Row row;
  row.method = method;
  std::vector<std::array<double, 2>> answers(targets.size());
  std::vector<char> accepted(targets.size());
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < targets.size(); ++i) {
    accepted[i] = solve(targets[i], &answers[i]);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  row.solves = static_cast<int>(targets.size());
  row.per_second = targets.size() / seconds;
  // Independent check of every answer, outside the timed loop.
  for (std::size_t i = 0; i < targets.size(); ++i) {
    if (!accepted[i]) {
      ++row.rejected;
      continue;
    }
    Intermesh<double> y;
    if (!linkage.Forward(answers[i][0], answers[i][1], &y)) {
      ++row.rejected;
      continue;
    }
    row.max_error_mm = std::max(
        {row.max_error_mm, std::abs(y.y1 - targets[i].y1), std::abs(y.y2 - targets[i].y2)});
    if (std::abs(targets[i].beta1) <= 89.0 && std::abs(targets[i].beta2) <= 89.0) {
      row.max_beta_error_deg =
          std::max({row.max_beta_error_deg, std::abs(answers[i][0] - targets[i].beta1),
                    std::abs(answers[i][1] - targets[i].beta2)});
    }
  }
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  const int count = argc > 1 ? std::max(1, std::atoi(argv[1])) : 20000;
  const Linkage linkage{LinkageGeometry{}};
  const auto nlopt_targets = MakeTargets(linkage, count);
  const auto closed_targets = MakeTargets(linkage, 10 * count);

  std::vector<Row> rows;
  rows.push_back(Measure("closed form (+ forward re-check)", linkage, closed_targets,
                         [&](const Target& t, std::array<double, 2>* out) {
                           const AngleSetpoint s = linkage.InverseClosedForm(t.y1, t.y2);
                           *out = {s.beta1_deg, s.beta2_deg};
                           return s.ok();
                         }));
  struct Variant {
    std::string name;
    Algorithm algorithm;
    InverseFormulation formulation;
    bool linearised_start;
    int divisor;  // slow derivative-free variants run on fewer targets
  };
  const Variant variants[] = {
      {"NLopt LD_SLSQP constrained, linearised start", Algorithm::kLdSlsqp,
       InverseFormulation::kConstrained, true, 1},
      {"NLopt LD_SLSQP constrained, start (0,0)", Algorithm::kLdSlsqp,
       InverseFormulation::kConstrained, false, 1},
      {"NLopt LD_SLSQP least squares", Algorithm::kLdSlsqp, InverseFormulation::kLeastSquares, true,
       1},
      {"NLopt LD_LBFGS least squares", Algorithm::kLdLbfgs, InverseFormulation::kLeastSquares, true,
       1},
      {"NLopt LD_MMA least squares", Algorithm::kLdMma, InverseFormulation::kLeastSquares, true,
       10},
      {"NLopt LN_BOBYQA least squares", Algorithm::kLnBobyqa, InverseFormulation::kLeastSquares,
       true, 10},
      {"NLopt LN_COBYLA constrained", Algorithm::kLnCobyla, InverseFormulation::kConstrained, true,
       10},
  };
  for (const auto& v : variants) {
    NloptInverseOptions options;
    options.algorithm = v.algorithm;
    options.formulation = v.formulation;
    options.linearised_start = v.linearised_start;
    options.max_evaluations = v.divisor > 1 ? 2000 : 200;
    const NloptInverse inverse(linkage, options);
    const std::vector<Target> subset(nlopt_targets.begin(),
                                     nlopt_targets.begin() + std::max(1, count / v.divisor));
    rows.push_back(
        Measure(v.name, linkage, subset, [&](const Target& t, std::array<double, 2>* out) {
          const NloptInverseResult r = inverse.Solve(t.y1, t.y2);
          *out = {r.beta1_deg, r.beta2_deg};
          return r.summary.accepted;
        }));
  }

  std::printf(
      "| method | solves | setpoints/s | max error (mm) | max |dbeta| (deg, |beta|<=89) | rejected "
      "|\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  for (const auto& r : rows) {
    std::printf("| %s | %d | %.3g | %.2g | %.2g | %d |\n", r.method.c_str(), r.solves, r.per_second,
                r.max_error_mm, r.max_beta_error_deg, r.rejected);
  }
  bool ok = true;
  for (int i : {0, 1}) {  // the closed form and the default NLopt method must be exact
    if (rows[i].rejected > 0 || rows[i].max_error_mm > kToleranceMm) {
      std::fprintf(stderr, "bench_leveller: MISMATCH in '%s': %d rejected, max error %.3g mm\n",
                   rows[i].method.c_str(), rows[i].rejected, rows[i].max_error_mm);
      ok = false;
    }
  }
  std::printf("targets: closed form >= %.0e/s: %s; NLopt (default) >= %.0e/s: %s\n",
              kClosedFormTargetPerS, rows[0].per_second >= kClosedFormTargetPerS ? "met" : "MISSED",
              kNloptTargetPerS, rows[1].per_second >= kNloptTargetPerS ? "met" : "MISSED");
  return ok ? 0 : 1;
}
