// Speed and accuracy of identification (issue 3). Not a test: it times.
//
// Five-mass scene, two spindle channels at 2 kHz over the bundled fit's window, 8 link parameters
// + bite time + gain and offset per channel (datasets/records/mill5_two_spindles.{spec,fit}.toml).
// In one run:
//  1. Noisy records (1 % noise, 12-bit, gain/offset errors; no recorder filter), --seeds of them:
//     each fitted from the scene's nominal values with the bundled robust start, for each way of
//     differentiating while iterating (sensitivities, forward and central differences).
//     Reported: median wall time, simulations, convergence
//     (every parameter within 0.1 standard error of the fit started at the truth), and per
//     parameter the RMSE over the seeds against the Cramér–Rao bound at the truth, with the
//     RMSE's own 95 % sampling spread, ±1.96/sqrt(2 seeds) relative.
//     --no-step-stop fits with FitOptions' statistical stop (remaining_step_se, rough_step_se)
//     off, for comparison.
//  2. Convergence from ±50 % starts on the noise-free record (--starts random starts, no scan):
//     the share that recovers every parameter to 1e-6.
//  3. SciPy (least_squares over solve_ivp) on the first noisy record, through
//     bench/identify/scipy_identify.py, when /usr/bin/python3 has scipy: from the nominal start
//     and from the truth. In the same run, on that record: MillKit's default search from the
//     nominal start (part 1's first fit) and MillKit's local fit from the truth (SciPy's own
//     task: one Levenberg–Marquardt fit of the whole record, no scan, no continuation, none of
//     the search's checks), median wall of --local-repeats, with the ratios to SciPy's wall and
//     the two fits' largest difference in MillKit's standard errors.
//  4. Threads: the default search on 1 and --threads T workers (2), median wall of
//     --local-repeats each, on the first noisy record and on the bundled measured record with its
//     config (the README command's fit); every value, standard error, the cost and the verdict
//     must be the same to the bit (a difference is a bug: non-zero exit).
// Exits non-zero when a fit from the truth fails to converge (a bug, not a slowness).
#include <glog/logging.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "millkit/driveline/scene_parameter.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/identify/record_generator.h"
#include "millkit/io/atomic_file.h"

using namespace millkit;
using namespace millkit::identify;

namespace {

const std::string kSource = MILLKIT_SOURCE_DIR;
constexpr double kNoise = 0.01;

struct Setup {
  driveline::Scene nominal;  // the engineer's prior (the scene file)
  driveline::Scene truth;    // with the spec's [truth]
  RecordSpec spec;
};

Setup LoadSetup() {
  Setup s;
  s.nominal = driveline::LoadScene(kSource + "/datasets/scenes/mill5_bite.toml");
  s.truth = s.nominal;
  s.spec = LoadRecordSpec(kSource + "/datasets/records/mill5_two_spindles.spec.toml", &s.truth);
  s.spec.defects.lowpass_Hz = 0.0;
  s.spec.defects.noise_fraction = kNoise;
  return s;
}

FitConfig Config(const Oscillogram& record, driveline::Scene* scene) {
  FitConfig config =
      LoadFitConfig(kSource + "/datasets/records/mill5_two_spindles.fit.toml", record, *scene);
  ApplySetValues(config, scene);
  for (auto& c : config.channels) c.lowpass_Hz = 0.0;
  return config;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// SciPy's task from a given start: one local fit of the whole record. The search's scan,
// continuation and checks off; the covariance (standard errors) still computed.
FitOptions LocalOnly() {
  FitOptions options;
  options.first_stage_divisor = 1.0;
  options.escalation_factor = 1;
  options.hops = 0;
  options.gap_kick = 0.0;
  options.curved_valley_ratio = 0.0;
  options.open_gap_points = 0;
  options.profile_points = 0;
  options.profile_relax_widening = 0.0;
  return options;
}

// Every fitted parameter's value, in the config's order.
std::vector<double> Values(const FitResult& fit) {
  std::vector<double> values;
  for (const auto& p : fit.parameters) values.push_back(p.value);
  return values;
}

// One of SciPy's fits, as scipy_identify.py reports it on its SCIPY_RESULT line.
struct SciPyFit {
  double wall_s = 0.0;
  long simulations = 0;
  std::vector<double> values;
};

// Runs `command`, echoes its output but its SCIPY_RESULT lines, and returns those by start label
// ("nominal", "truth"). Empty when the command fails.
std::map<std::string, SciPyFit> RunSciPy(const std::string& command) {
  std::map<std::string, SciPyFit> fits;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return fits;
  std::string line;
  char chunk[4096];
  while (std::fgets(chunk, sizeof(chunk), pipe) != nullptr) {
    line += chunk;
    if (line.empty() || line.back() != '\n') continue;
    if (line.rfind("SCIPY_RESULT ", 0) == 0) {
      std::istringstream in(line.substr(13));
      std::string label;
      SciPyFit fit;
      in >> label >> fit.wall_s >> fit.simulations;
      for (double v; in >> v;) fit.values.push_back(v);
      fits[label] = fit;
    } else {
      std::fputs(line.c_str(), stdout);
    }
    line.clear();
  }
  if (pclose(pipe) != 0) fits.clear();
  std::fflush(stdout);
  return fits;
}

}  // namespace

int main(int argc, char** argv) {
  int seeds = 100;
  int random_starts = 100;
  int local_repeats = 11;
  int threads = 2;
  bool step_stop = true;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--no-step-stop") {
      step_stop = false;
    } else if (flag == "--seeds" && i + 1 < argc) {
      seeds = std::atoi(argv[++i]);
    } else if (flag == "--starts" && i + 1 < argc) {
      random_starts = std::atoi(argv[++i]);
    } else if (flag == "--local-repeats" && i + 1 < argc) {
      local_repeats = std::max(1, std::atoi(argv[++i]));
    } else if (flag == "--threads" && i + 1 < argc) {
      threads = std::clamp(std::atoi(argv[++i]), 2, 256);
    } else {
      std::fprintf(stderr,
                   "usage: %s [--seeds N (100)] [--starts N (100)] [--local-repeats N (11)] "
                   "[--threads T (2)] [--no-step-stop]\n",
                   argv[0]);
      return 2;
    }
  }
  FLAGS_minloglevel = 3;  // Ceres' glog: a start that fails to simulate is data, not a message
  Setup setup = LoadSetup();
  int status = 0;

  // Cramér–Rao bound at the truth: noise σ_c = kNoise × peak |g m_c| of the true record.
  RecordSpec clean_spec = setup.spec;
  clean_spec.defects.noise_fraction = 0.0;
  clean_spec.defects.bits = 0;
  const Oscillogram clean = GenerateRecord(setup.truth, clean_spec);
  driveline::Scene scene = setup.nominal;
  const FitConfig clean_config = Config(clean, &scene);
  std::vector<double> noise;
  for (size_t c = 0; c < clean_spec.channels.size(); ++c) {
    double peak = 0.0;
    for (double v : clean.values[c]) {
      peak = std::max(peak, std::abs(v - clean_spec.channels[c].offset_Nm));
    }
    // The generator's σ is kNoise × peak |m| (before gain); the fit sees g·m: noise in the
    // fit's units is σ/g.
    noise.push_back(kNoise * peak / clean_spec.channels[c].gain / clean_spec.channels[c].gain);
  }
  std::vector<double> bound = CramerRaoBound(setup.truth, clean, clean_config, noise, FitOptions{});
  std::vector<double> truth;
  for (const auto& free : clean_config.free) truth.push_back(free.parameter.Get(setup.truth));

  std::printf(
      "## Identification: five-mass bite, 2 channels at 2 kHz, %zu parameters + 4 nuisance\n\n",
      clean_config.free.size());
  std::printf(
      "| derivatives | fits | converged | median wall s | median simulations | "
      "worst RMSE / CRLB, all fits | the same, converged fits |\n|---|---|---|---|---|---|---|\n");
  Oscillogram first_noisy;
  FitResult first_search;  // the default fit of the first noisy record
  std::vector<double> default_rmse(truth.size(), 0.0);
  for (const Derivatives derivatives :
       {Derivatives::kSensitivity, Derivatives::kForward, Derivatives::kCentral}) {
    FitOptions options;
    options.derivatives = derivatives;
    if (!step_stop) options.remaining_step_se = options.rough_step_se = 0.0;
    std::vector<double> walls;
    std::vector<long> sims;
    std::vector<double> sum_sq(truth.size(), 0.0);
    std::vector<double> sum_sq_converged(truth.size(), 0.0);
    int converged = 0;
    for (int seed = 1; seed <= seeds; ++seed) {
      RecordSpec spec = setup.spec;
      spec.defects.seed = 5000 + seed;
      const Oscillogram record = GenerateRecord(setup.truth, spec);
      if (seed == 1) first_noisy = record;
      driveline::Scene fit_scene = setup.nominal;
      FitConfig config = Config(record, &fit_scene);
      const auto start = std::chrono::steady_clock::now();
      const FitResult fit = Fit(fit_scene, record, config, options);
      walls.push_back(Seconds(start));
      sims.push_back(fit.summary.simulations);
      if (seed == 1 && derivatives == FitOptions{}.derivatives) {
        first_search = fit;
        first_search.summary.wall_time_s = walls.back();
      }
      // Reference: the same record fitted from the truth, no scan.
      FitConfig from_truth = config;
      for (size_t i = 0; i < truth.size(); ++i) from_truth.free[i].start = truth[i];
      from_truth.scan_points = 0;
      from_truth.starts = 1;
      const FitResult reference = Fit(fit_scene, record, from_truth, options);
      if (!reference.summary.success) {
        std::fprintf(stderr, "bench_identify: the fit from the truth failed (seed %d): %s\n", seed,
                     reference.summary.message.c_str());
        status = 1;
        continue;
      }
      bool same = fit.summary.success;
      for (size_t i = 0; same && i < truth.size(); ++i) {
        same = std::abs(fit.parameters[i].value - reference.parameters[i].value) <=
               0.1 * reference.parameters[i].standard_error;
      }
      converged += same ? 1 : 0;
      for (size_t i = 0; i < truth.size(); ++i) {
        sum_sq[i] += std::pow(fit.parameters[i].value - truth[i], 2);
        if (same) sum_sq_converged[i] += std::pow(fit.parameters[i].value - truth[i], 2);
      }
    }
    if (derivatives == FitOptions{}.derivatives) {
      for (size_t i = 0; i < truth.size(); ++i) default_rmse[i] = std::sqrt(sum_sq[i] / seeds);
    }
    std::sort(walls.begin(), walls.end());
    std::sort(sims.begin(), sims.end());
    const auto worst = [&](const std::vector<double>& squares, int count) {
      double ratio_max = 0.0;
      std::string name;
      for (size_t i = 0; i < truth.size(); ++i) {
        const double ratio = std::sqrt(squares[i] / std::max(count, 1)) / bound[i];
        if (ratio > ratio_max) {
          ratio_max = ratio;
          name = clean_config.free[i].parameter.name;
        }
      }
      char text[160];
      std::snprintf(text, sizeof(text), "%.2f ± %.2f (%s)", ratio_max,
                    1.96 * ratio_max / std::sqrt(2.0 * std::max(count, 1)), name.c_str());
      return std::string(text);
    };
    std::printf("| %s | %d | %d | %.2f | %ld | %s | %s |\n", DerivativesName(derivatives), seeds,
                converged, walls[walls.size() / 2], sims[sims.size() / 2],
                worst(sum_sq, seeds).c_str(), worst(sum_sq_converged, converged).c_str());
    std::fflush(stdout);
  }
  std::printf(
      "\nCramér–Rao bound at the truth (1 %% noise) and the default (sensitivity) fits' RMSE:\n\n| "
      "parameter | truth | CRLB | RMSE / CRLB |\n|---|---|---|---|\n");
  for (size_t i = 0; i < truth.size(); ++i) {
    std::printf("| %s | %.6g | %.3g | %.2f |\n", clean_config.free[i].parameter.name.c_str(),
                truth[i], bound[i], default_rmse[i] / bound[i]);
  }

  // Convergence from ±50 % starts, noise-free record, continuation alone (no scan, one start).
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> factor(0.5, 1.5);
  int recovered = 0;
  std::vector<double> walls;
  for (int k = 0; k < random_starts; ++k) {
    driveline::Scene fit_scene = setup.nominal;
    FitConfig config = Config(clean, &fit_scene);
    config.scan_points = 0;
    config.starts = 1;
    for (size_t i = 0; i < truth.size(); ++i) {
      auto& free = config.free[i];
      const double span = free.parameter.name == "bite_time" ? 0.02 : truth[i];
      const double value = free.parameter.name == "bite_time"
                               ? truth[i] + (factor(random) - 1.0) * span
                               : truth[i] * factor(random);
      free.start = std::clamp(value, free.lower, free.upper);
    }
    const auto start = std::chrono::steady_clock::now();
    const FitResult fit = Fit(fit_scene, clean, config, FitOptions{});
    walls.push_back(Seconds(start));
    bool ok = fit.summary.success;
    for (size_t i = 0; ok && i < truth.size(); ++i) {
      ok = std::abs(fit.parameters[i].value - truth[i]) <= 1e-6 * std::abs(truth[i]);
    }
    recovered += ok ? 1 : 0;
  }
  std::sort(walls.begin(), walls.end());
  std::printf(
      "\n±50 %% starts, noise-free record, no scan: %d of %d recover every parameter to "
      "1e-6 (median %.2f s per fit)\n",
      recovered, random_starts, walls.empty() ? 0.0 : walls[walls.size() / 2]);
  std::fflush(stdout);

  // MillKit's local fit from the truth on the first noisy record: SciPy's task from there.
  if (seeds < 1) return status;
  driveline::Scene local_scene = setup.nominal;
  FitConfig local_config = Config(first_noisy, &local_scene);
  for (size_t i = 0; i < truth.size(); ++i) local_config.free[i].start = truth[i];
  local_config.scan_points = 0;
  local_config.starts = 1;
  // The median wall of local_repeats local fits of the first noisy record from `config`'s starts.
  const auto local_fit = [&](const FitConfig& config, FitResult* result) {
    std::vector<double> local_walls;
    for (int k = 0; k < local_repeats; ++k) {
      const auto start = std::chrono::steady_clock::now();
      *result = Fit(local_scene, first_noisy, config, LocalOnly());
      local_walls.push_back(Seconds(start));
    }
    std::sort(local_walls.begin(), local_walls.end());
    return local_walls[local_walls.size() / 2];
  };
  FitResult local;
  const double local_wall = local_fit(local_config, &local);
  // And from the nominal start, as SciPy's first fit.
  FitConfig nominal_config = local_config;
  for (size_t i = 0; i < truth.size(); ++i) {
    nominal_config.free[i].start = first_search.parameters[i].start;
  }
  FitResult local_nominal;
  const double local_nominal_wall = local_fit(nominal_config, &local_nominal);
  // The default search's fit of the record against the local one, in the local one's standard
  // errors (the same minimum: within a small fraction of one).
  const auto apart = [&](const std::vector<double>& values) {
    double worst = 0.0;
    for (size_t i = 0; i < truth.size() && i < values.size(); ++i) {
      worst = std::max(worst, std::abs(values[i] - local.parameters[i].value) /
                                  local.parameters[i].standard_error);
    }
    return worst;
  };
  const std::vector<double> search_values = Values(first_search);
  const std::vector<double> local_nominal_values = Values(local_nominal);
  std::printf(
      "\nMillKit's local fit from the truth, first noisy record (one Levenberg–Marquardt fit of "
      "the whole record and its covariance; no scan, continuation or checks): %s, median %.4f s "
      "of %d, %ld simulations; the default search's fit of the record (from the nominal start, "
      "%.3f s) lies %.3g standard errors from it\n",
      local.summary.success ? "converged" : "FAILED", local_wall, local_repeats,
      local.summary.simulations, first_search.summary.wall_time_s, apart(search_values));
  std::fflush(stdout);
  if (!local.summary.success) status = 1;

  // The default search on 1 and `threads` workers: the same fit, in less wall time.
  std::printf(
      "\nThe default search on 1 and %d threads (median wall of %d each; the same values, "
      "standard errors, cost and verdict to the bit):\n\n| record | runs | 1 thread s | %d threads "
      "s | speed-up | the same |\n|---|---|---|---|---|---|\n",
      threads, local_repeats, threads);
  const auto on_threads = [&](const char* label, const driveline::Scene& fit_scene,
                              const Oscillogram& record, const FitConfig& config) {
    FitResult results[2];
    double medians[2];
    for (int k = 0; k < 2; ++k) {
      FitOptions options;
      options.threads = k == 0 ? 1 : threads;
      std::vector<double> fit_walls;
      for (int repeat = 0; repeat < local_repeats; ++repeat) {
        const auto start = std::chrono::steady_clock::now();
        results[k] = Fit(fit_scene, record, config, options);
        fit_walls.push_back(Seconds(start));
      }
      std::sort(fit_walls.begin(), fit_walls.end());
      medians[k] = fit_walls[fit_walls.size() / 2];
    }
    bool same = results[0].summary.cost == results[1].summary.cost &&
                results[0].summary.verdict == results[1].summary.verdict &&
                results[0].parameters.size() == results[1].parameters.size();
    for (size_t i = 0; same && i < results[0].parameters.size(); ++i) {
      same = results[0].parameters[i].value == results[1].parameters[i].value &&
             results[0].parameters[i].standard_error == results[1].parameters[i].standard_error;
    }
    if (!same) status = 1;
    std::printf("| %s | %ld | %.3f | %.3f | %.2f | %s |\n", label, results[0].summary.simulations,
                medians[0], medians[1], medians[0] / medians[1], same ? "yes" : "NO");
    std::fflush(stdout);
  };
  {
    driveline::Scene fit_scene = setup.nominal;
    const FitConfig config = Config(first_noisy, &fit_scene);
    on_threads("first noisy record (no recorder filter)", fit_scene, first_noisy, config);
  }
  {
    const Oscillogram measured =
        LoadOscillogram(kSource + "/datasets/records/mill5_two_spindles.csv");
    driveline::Scene fit_scene = setup.nominal;
    FitConfig config = LoadFitConfig(kSource + "/datasets/records/mill5_two_spindles.fit.toml",
                                     measured, fit_scene);
    ApplySetValues(config, &fit_scene);
    on_threads("bundled measured record, its config (the README command)", fit_scene, measured,
               config);
  }

  // SciPy on the first noisy record.
  // This process's own directory (two runs at once do not share or remove each other's).
  const auto dir = std::filesystem::temp_directory_path() /
                   ("millkit_bench_identify_" + std::to_string(static_cast<long>(getpid())));
  std::filesystem::create_directories(dir);
  WriteFileAtomically(dir / "record.csv", FormatOscillogram(first_noisy));
  const std::string script = kSource + "/bench/identify/scipy_identify.py";
  const std::string command =
      "/usr/bin/python3 -c 'import scipy' 2>/dev/null && /usr/bin/python3 '" + script + "' '" +
      kSource + "/datasets/scenes/mill5_bite.toml' '" + (dir / "record.csv").string() + "'";
  std::printf(
      "\nSciPy least_squares over solve_ivp, same record and bounds, from the nominal start and "
      "from the truth:\n\n");
  std::fflush(stdout);
  const std::map<std::string, SciPyFit> scipy = RunSciPy(command);
  std::filesystem::remove_all(dir);
  if (scipy.count("nominal") == 0 || scipy.count("truth") == 0) {
    std::printf("(SciPy not available or failed)\n");
    return status;
  }
  const SciPyFit& from_nominal = scipy.at("nominal");
  const SciPyFit& from_truth = scipy.at("truth");
  std::printf(
      "\nSpeed against SciPy, same record, one run (distance: the largest parameter difference "
      "from MillKit's local fit from the truth, in its standard errors):\n\n"
      "| MillKit | SciPy | MillKit wall s | SciPy wall s | SciPy / MillKit | MillKit's distance "
      "| SciPy's distance |\n|---|---|---|---|---|---|---|\n");
  const std::vector<double> local_values = Values(local);
  const auto row = [&](const char* millkit, double wall, const std::vector<double>& values,
                       const char* scipy_start, const SciPyFit& scipy_fit) {
    std::printf("| %s | from %s | %.4f | %.2f | %.0f× | %.3g | %.3g |\n", millkit, scipy_start,
                wall, scipy_fit.wall_s, scipy_fit.wall_s / wall, apart(values),
                apart(scipy_fit.values));
  };
  const double search_wall = first_search.summary.wall_time_s;
  row("local fit from the truth", local_wall, local_values, "the truth", from_truth);
  row("default search from the nominal start", search_wall, search_values, "the truth", from_truth);
  row("local fit from the nominal start", local_nominal_wall, local_nominal_values,
      "the nominal start", from_nominal);
  row("default search from the nominal start", search_wall, search_values, "the nominal start",
      from_nominal);
  return status;
}
