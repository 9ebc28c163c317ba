// The cost and accuracy of one Jacobian of the simulated channels (issue 15 item 1): forward
// sensitivities of the exact solver against forward and central differences (step 1e-6 of each
// parameter's bound range, what the fit takes), each checked against a reference, central
// differences at 1e-5 and 5e-6 of the parameter extrapolated (O(h⁴)). On the bundled bite
// (mill5_bite with its two-spindle record and fit config) and on random lines (the truth, their
// default fit configs), at the parameter values the fit starts from.
//
// Usage: bench_sensitivity [--cases N (20)] [--repeats R (5)] [--variant V[+V]] [--profile RUNS]
// --variant draws the random lines as bench_random_lines does (lowpass: a recorder low-pass on
// the channels, no-pull, linear, ...).
// Reports per case the wall time of one plain simulation, one with sensitivities, P + 1 and
// 2P + 1 simulations, and the error of each Jacobian (largest difference from the reference over
// its largest entry, per parameter, worst parameter).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "identify/random_line.h"
#include "millkit/driveline/scene.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"

using namespace millkit;
using namespace millkit::identify;

namespace {

struct Case {
  std::string name;
  driveline::Scene scene;
  Oscillogram record;
  FitConfig config;
};

// Every channel's samples, stacked, and each parameter's column of derivatives.
using Columns = std::vector<Eigen::VectorXd>;

bool Run(const Case& c, Eigen::VectorXd* torque, std::vector<Eigen::MatrixXd>* derivatives,
         std::string* unavailable) {
  const auto [begin, end] = c.record.WindowRange(c.config.window_start_s, c.config.window_end_s);
  std::vector<Eigen::VectorXd> torques;
  std::string why;
  std::vector<driveline::SceneParameter> parameters;
  for (const auto& free : c.config.free) parameters.push_back(free.parameter);
  const bool ok =
      derivatives != nullptr
          ? SimulateChannels(c.scene, c.record, TimeOrigin(c.config, c.record), c.config.channels,
                             begin, end, &torques, &why, parameters, derivatives, unavailable)
          : SimulateChannels(c.scene, c.record, TimeOrigin(c.config, c.record), c.config.channels,
                             begin, end, &torques, &why);
  if (!ok) return false;
  Eigen::Index size = 0;
  for (const auto& t : torques) size += t.size();
  torque->resize(size);
  Eigen::Index at = 0;
  for (const auto& t : torques) {
    torque->segment(at, t.size()) = t;
    at += t.size();
  }
  return true;
}

Eigen::VectorXd At(const Case& c, int j, double value) {
  Case probe = c;
  c.config.free[j].parameter.Set(value, &probe.scene);
  Eigen::VectorXd torque;
  Run(probe, &torque, nullptr, nullptr);
  return torque;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  int cases = 20;
  int repeats = 5;
  int profile = 0;  // > 0: only this many sensitivity runs of the bundled bite (for a profiler)
  std::vector<RandomLineVariant> variants;
  for (int i = 1; i < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--cases" && i + 1 < argc) {
      cases = std::atoi(argv[i + 1]);
    } else if (flag == "--repeats" && i + 1 < argc) {
      repeats = std::atoi(argv[i + 1]);
    } else if (flag == "--profile" && i + 1 < argc) {
      profile = std::atoi(argv[i + 1]);
    } else if (flag == "--variant" && i + 1 < argc &&
               ParseRandomLineVariants(argv[i + 1], &variants)) {
    } else {
      std::fprintf(stderr,
                   "usage: %s [--cases N (20)] [--repeats R (5)] [--variant V[+V]] "
                   "[--profile RUNS]\n",
                   argv[0]);
      return 2;
    }
  }
  std::vector<Case> all;
  {
    const std::string source = MILLKIT_SOURCE_DIR;
    Case bundled;
    bundled.name = "bundled bite";
    bundled.scene = driveline::LoadScene(source + "/datasets/scenes/mill5_bite.toml");
    bundled.record = LoadOscillogram(source + "/datasets/records/mill5_two_spindles.csv");
    bundled.config = LoadFitConfig(source + "/datasets/records/mill5_two_spindles.fit.toml",
                                   bundled.record, bundled.scene);
    ApplySetValues(bundled.config, &bundled.scene);
    all.push_back(std::move(bundled));
  }
  if (profile > 0) {
    Eigen::VectorXd torque;
    std::vector<Eigen::MatrixXd> derivatives;
    std::string unavailable;
    for (int r = 0; r < profile; ++r) Run(all.front(), &torque, &derivatives, &unavailable);
    return 0;
  }
  for (int k = 1; k <= cases; ++k) {
    const RandomLineCase line = MakeRandomLineCase(static_cast<unsigned long>(k), variants);
    all.push_back({"seed " + std::to_string(k), line.prior, line.record, line.config});
  }
  std::printf("## One Jacobian of the simulated channels: sensitivities vs finite differences\n\n");
  std::printf(
      "| case | P | samples | plain ms | sensitivities ms | forward (P+1) ms | central "
      "(2P+1) ms | error: sensitivities | forward | central |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<double> ratio_forward, ratio_central, ratio_plain, error_s, error_f, error_c;
  for (const Case& c : all) {
    const int p = static_cast<int>(c.config.free.size());
    Eigen::VectorXd torque;
    std::vector<Eigen::MatrixXd> derivatives;
    std::string unavailable;
    double plain = 1e300, sens = 1e300, forward = 1e300, central = 1e300;
    Eigen::MatrixXd jac_s, jac_f(0, 0), jac_c;
    for (int r = 0; r < repeats; ++r) {
      auto start = std::chrono::steady_clock::now();
      Run(c, &torque, nullptr, nullptr);
      plain = std::min(plain, Seconds(start));
      start = std::chrono::steady_clock::now();
      Run(c, &torque, &derivatives, &unavailable);
      sens = std::min(sens, Seconds(start));
      // Forward and central differences with the fit's step: 1e-6 of the bound range.
      start = std::chrono::steady_clock::now();
      Eigen::VectorXd base;
      Run(c, &base, nullptr, nullptr);
      jac_f.resize(base.size(), p);
      for (int j = 0; j < p; ++j) {
        const auto& free = c.config.free[j];
        const double h = 1e-6 * (free.upper - free.lower);
        jac_f.col(j) = (At(c, j, free.parameter.Get(c.scene) + h) - base) / h;
      }
      forward = std::min(forward, Seconds(start));
      start = std::chrono::steady_clock::now();
      Run(c, &base, nullptr, nullptr);
      jac_c.resize(base.size(), p);
      for (int j = 0; j < p; ++j) {
        const auto& free = c.config.free[j];
        const double h = 1e-6 * (free.upper - free.lower);
        const double v = free.parameter.Get(c.scene);
        jac_c.col(j) = (At(c, j, v + h) - At(c, j, v - h)) / (2 * h);
      }
      central = std::min(central, Seconds(start));
    }
    if (!unavailable.empty()) {
      std::printf("| %s | %d | %ld | sensitivities unavailable: %s |\n", c.name.c_str(), p,
                  static_cast<long>(torque.size()), unavailable.c_str());
      continue;
    }
    jac_s.resize(torque.size(), p);
    for (int j = 0; j < p; ++j) {
      Eigen::Index at = 0;
      for (const auto& d : derivatives) {
        jac_s.col(j).segment(at, d.rows()) = d.col(j);
        at += d.rows();
      }
    }
    // The reference: extrapolated central differences at 1e-5 and 5e-6 of the value (or range).
    // Where the two differ by more than 1e-3 of their size, an event (an impact starting or
    // ending) moves past a sample within ± h: no derivative describes that sample, and the case
    // has no reference (the test, tests/identify/sensitivity_test.cpp, drops such samples).
    double es = 0, ef = 0, ec = 0, spread = 0;
    for (int j = 0; j < p; ++j) {
      const auto& free = c.config.free[j];
      const double v = free.parameter.Get(c.scene);
      const double h = 1e-5 * std::max(std::abs(v), 1e-3 * (free.upper - free.lower));
      const Eigen::VectorXd coarse = (At(c, j, v + h) - At(c, j, v - h)) / (2 * h);
      const Eigen::VectorXd fine = (At(c, j, v + h / 2) - At(c, j, v - h / 2)) / h;
      const Eigen::VectorXd reference = (4 * fine - coarse) / 3;
      const double size = std::max(reference.cwiseAbs().maxCoeff(), 1e-300);
      spread = std::max(spread, (fine - coarse).cwiseAbs().maxCoeff() / size);
      es = std::max(es, (jac_s.col(j) - reference).cwiseAbs().maxCoeff() / size);
      ef = std::max(ef, (jac_f.col(j) - reference).cwiseAbs().maxCoeff() / size);
      ec = std::max(ec, (jac_c.col(j) - reference).cwiseAbs().maxCoeff() / size);
    }
    ratio_plain.push_back(sens / plain);
    ratio_forward.push_back(forward / sens);
    ratio_central.push_back(central / sens);
    if (spread > 1e-3) {
      std::printf(
          "| %s | %d | %ld | %.2f | %.2f | %.2f | %.2f | no reference: an event moves past a "
          "sample within the reference's step (its two differences disagree by %.0e) | | |\n",
          c.name.c_str(), p, static_cast<long>(torque.size()), 1e3 * plain, 1e3 * sens,
          1e3 * forward, 1e3 * central, spread);
      continue;
    }
    std::printf("| %s | %d | %ld | %.2f | %.2f | %.2f | %.2f | %.1e | %.1e | %.1e |\n",
                c.name.c_str(), p, static_cast<long>(torque.size()), 1e3 * plain, 1e3 * sens,
                1e3 * forward, 1e3 * central, es, ef, ec);
    error_s.push_back(es);
    error_f.push_back(ef);
    error_c.push_back(ec);
  }
  std::printf(
      "\nMedians over %zu cases: sensitivities cost %.1f plain runs; forward differences "
      "take %.2f× and central %.2f× the sensitivities' time; over the %zu with a reference, "
      "worst-parameter error %.1e (sensitivities), %.1e (forward), %.1e (central).\n",
      ratio_plain.size(), Median(ratio_plain), Median(ratio_forward), Median(ratio_central),
      error_s.size(), Median(error_s), Median(error_f), Median(error_c));
  return 0;
}
