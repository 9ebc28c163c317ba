// Identification over seeded random drive lines (issue 12). Not a test: it measures how the
// default fit (what a new user runs: DefaultFitConfig, FitOptions{}) does on lines nobody tuned it
// for, identify/random_line.h.
//
// For each seed: the fit from the prior, z = (estimate − truth) / standard error of every
// parameter the fit calls identifiable, and the fit's verdict. A case is good when every such z
// lies within 3 and the verdict is ok. Reported: the share of good cases, silent wrong answers
// (worst |z| > 5 with verdict ok: the failure that matters most), false alarms (within 3 SE but
// not ok), the verdicts, the RMS of z (≈ 1 when the standard errors are calibrated), the share of
// parameters flagged not identifiable, and wall time and simulations per fit.
//
// Each case that is not good is fitted once more from the truth (no scan, one start, the default
// fit's final channel weights so that the two costs compare): a lower cost there means the default
// fit stopped in a wrong minimum; the same or a higher cost and a large |z| mean the data prefer
// the wrong answer or the standard errors are not calibrated. The cost at the true values, in the
// same weights, tells which: far above the fit's (χ² = 2 × the difference, over noise_scale², well
// past 9) the record itself puts the truth that far away; only a little above, the standard errors
// are too small for the misfit's shape there.
//
// --search-seed K adds K to the seeds of the scan's points and of the basin hops: the same lines
// fitted with other random choices, which shows how much a verdict owes to luck.
//
// --scipy N fits the first N lines also with SciPy (bench/identify/scipy_fit.py: least_squares
// over solve_ivp, one local fit, no scan, when /usr/bin/python3 has scipy), from the same start
// and from the truth, and scores its answers in MillKit's standard errors: wall time,
// simulations and worst |z| side by side with MillKit's fit.
//
// --variant drive|wide-prior|stiffness|no-pull|linear|step-load|lowpass|fast-lowpass fits lines
// the base draw never makes (a speed-PI drive, a prior three times off, a fitted stiffness, the
// no_pull or the linear contact law, loads applied as steps, a recorder anti-alias filter, a
// recorder filter above half the rate;
// identify/random_line.h); variants combine with '+' (no-pull+lowpass). --scipy goes with the base
// lines only: bench/identify/scipy_fit.py models no drive.
//
// Usage: bench_random_lines [--cases N (200)] [--first-seed S (1)] [--threads N] [--search-seed K]
//                           [--variant V[+V...]]  (V: base, drive, wide-prior, stiffness,
//                                                  no-pull, linear, step-load, lowpass,
//                                                  fast-lowpass)
//                           [--derivatives sensitivity|forward|central] [--scipy N] [--verbose]
// Exits 1 when a case throws (printed, counted as crashed), else 0.
#include <glog/logging.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "identify/fit_model.h"
#include "identify/random_line.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/io/output_files.h"

using namespace millkit;
using namespace millkit::identify;

namespace {

constexpr double kWithin = 3.0;  // |z| of a good estimate
constexpr double kWrong = 5.0;   // |z| of a silent wrong answer

// z of every identifiable parameter and the worst of them.
struct Scores {
  std::vector<double> z;
  bool finite_se = true;  // every identifiable parameter has a finite, positive standard error
  double worst_z = 0.0;   // signed; 0 when nothing is identifiable
  std::string worst_name;
  int unidentifiable = 0;
};

Scores Score(const FitResult& fit, const RandomLineCase& c) {
  Scores s;
  for (size_t i = 0; i < fit.parameters.size() && i < c.truth_values.size(); ++i) {
    const ParameterEstimate& p = fit.parameters[i];
    if (p.name != c.config.free[i].parameter.name) {
      throw std::logic_error("parameter " + p.name + " where " + c.config.free[i].parameter.name +
                             " was expected");
    }
    if (!p.identifiable) {
      ++s.unidentifiable;
      continue;
    }
    const bool finite = std::isfinite(p.standard_error) && p.standard_error > 0.0;
    s.finite_se = s.finite_se && finite;
    const double z = finite ? (p.value - c.truth_values[i]) / p.standard_error
                            : std::numeric_limits<double>::infinity();
    s.z.push_back(z);
    if (s.worst_name.empty() || std::abs(z) > std::abs(s.worst_z)) {
      s.worst_z = z;
      s.worst_name = p.name;
    }
  }
  return s;
}

bool Within(const Scores& s) {
  for (double z : s.z) {
    if (!(std::abs(z) <= kWithin)) return false;
  }
  return true;
}

std::string Verdict(const FitSummary& summary) {
  if (!summary.verdict.empty()) return summary.verdict;
  return summary.success ? "ok" : "failed";
}

struct CaseResult {
  unsigned long seed = 0;
  std::string description;
  std::string verdict;
  Scores scores;
  bool within = false;
  double cost = 0.0;
  double wall_s = 0.0;
  long simulations = 0;
  int free = 0;
  // The fit started at the truth, for the cases that are not good.
  double truth_cost = 0.0;
  double cost_at_truth = 0.0;  // the cost of the true values, in the default fit's weights
  Scores truth_scores;
  std::string truth_verdict;
};

// Nearest-rank quantile of a sorted sample.
template <typename T>
T Quantile(const std::vector<T>& sorted, double q) {
  if (sorted.empty()) return T{};
  const size_t rank = static_cast<size_t>(std::ceil(q * static_cast<double>(sorted.size())));
  return sorted[std::clamp<size_t>(rank, 1, sorted.size()) - 1];
}

double Share(int part, int whole) { return whole > 0 ? 100.0 * part / whole : 0.0; }

// One of SciPy's local fits of a line.
struct SciPyFit {
  bool ran = false;
  double wall_s = 0.0;
  long simulations = 0;
  double worst_z = 0.0;  // |z| in MillKit's standard errors
  std::string worst_name;
};

struct SciPyLine {
  unsigned long seed = 0;
  std::string verdict;  // MillKit's
  bool within = false;  // MillKit's
  double worst_z = 0.0;
  double wall_s = 0.0;
  SciPyFit from_start, from_truth;
  std::string note;  // why SciPy did not run
};

const std::string kScript = std::string(MILLKIT_SOURCE_DIR) + "/bench/identify/scipy_fit.py";

bool SciPyAvailable() {
  return std::system("/usr/bin/python3 -c 'import scipy' > /dev/null 2>&1") == 0;
}

// The line in scipy_fit.py's form: its model as scipy_simulate.load gives it, the record's window,
// the channels' links and the free parameters with MillKit's standard errors; runs the script
// and reads its two lines.
void RunSciPy(const RandomLineCase& c, const FitResult& fit, SciPyLine* line) {
  const driveline::Scene& scene = c.prior;
  if (scene.drive || scene.contact != driveline::ContactLaw::kLimited) {
    line->note = "a drive or another contact law";
    return;
  }
  nlohmann::json model;
  model["law"] = "limited";
  model["duration"] = scene.duration_s;
  model["rate"] = scene.sample_rate_Hz;
  model["speed"] = scene.initial_speed_rad_per_s;
  for (const auto& mass : scene.masses) {
    model["J"].push_back(mass.inertia_kg_m2);
    model["masses"].push_back(mass.name);
  }
  for (const auto& link : scene.links) {
    if (link.ratio != 1.0) {
      line->note = "a gear ratio";
      return;
    }
    model["links"].push_back({{"name", link.name},
                              {"a", link.from},
                              {"b", link.to},
                              {"c", link.stiffness_Nm_per_rad},
                              {"d", link.damping_Nms_per_rad},
                              {"bl", link.backlash_rad},
                              {"gp", link.gap_position}});
  }
  for (const auto& source : scene.torques) {
    if (source.times_s.size() != 2) {
      line->note = "a torque that is not one ramp";
      return;
    }
    model["sources"].push_back({{"m", source.mass},
                                {"before", source.values_Nm[0]},
                                {"after", source.values_Nm[1]},
                                {"start", source.times_s[0]},
                                {"rise", source.times_s[1] - source.times_s[0]}});
  }
  nlohmann::json doc;
  doc["model"] = model;
  std::vector<int> columns;
  for (const auto& channel : c.config.channels) {
    columns.push_back(c.record.ChannelIndex(channel.column));
    doc["channels"].push_back(
        scene.LinkIndex(channel.link.empty() ? channel.column : channel.link));
  }
  for (size_t k = 0; k < c.record.time_s.size(); ++k) {
    const double t = c.record.time_s[k];
    if (t < c.config.window_start_s || t > c.config.window_end_s) continue;
    doc["t"].push_back(t);
  }
  for (const int column : columns) {
    nlohmann::json values = nlohmann::json::array();
    for (size_t k = 0; k < c.record.time_s.size(); ++k) {
      const double t = c.record.time_s[k];
      if (t < c.config.window_start_s || t > c.config.window_end_s) continue;
      values.push_back(c.record.values[column][k]);
    }
    doc["y"].push_back(values);
  }
  for (size_t i = 0; i < c.config.free.size(); ++i) {
    const FreeParameter& free = c.config.free[i];
    const ParameterEstimate& estimate = fit.parameters[i];
    const bool scored = estimate.identifiable && std::isfinite(estimate.standard_error) &&
                        estimate.standard_error > 0.0;
    doc["free"].push_back({{"name", free.parameter.name},
                           {"lower", free.lower},
                           {"upper", free.upper},
                           {"start", free.start},
                           {"truth", c.truth_values[i]},
                           {"se", scored ? nlohmann::json(estimate.standard_error) : nullptr}});
  }
  // A new file of its own (mkstemp: never another file), removed after the run and, through the
  // project's cleanup handler, on Ctrl-C.
  std::string name =
      (std::filesystem::temp_directory_path() / "millkit_scipy_line_XXXXXX").string();
  const int fd = mkstemp(name.data());
  if (fd < 0) {
    line->note = "no temporary file in " + std::filesystem::temp_directory_path().string();
    return;
  }
  const std::filesystem::path path(name);
  RegisterTemporaryFile(path);
  const std::string text = doc.dump();
  bool written = true;
  for (size_t at = 0; written && at < text.size();) {
    const ssize_t n = write(fd, text.data() + at, text.size() - at);
    written = n > 0;
    at += written ? static_cast<size_t>(n) : 0;
  }
  close(fd);
  const auto remove_file = [&path] {
    std::filesystem::remove(path);
    ReleaseTemporaryFile(path);
  };
  if (!written) {
    line->note = "cannot write " + path.string();
    remove_file();
    return;
  }
  const std::string command = "/usr/bin/python3 '" + kScript + "' '" + path.string() + "' 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) {
    line->note = "python3 did not start";
    remove_file();
    return;
  }
  std::array<char, 4096> buffer{};
  std::string output;
  while (std::fgets(buffer.data(), buffer.size(), pipe) != nullptr) {
    output += buffer.data();
    char from[16] = {}, name[256] = {};
    SciPyFit result;
    int status = 0;
    if (std::sscanf(buffer.data(), "SCIPY %15s %lf %ld %d %lf %255s", from, &result.wall_s,
                    &result.simulations, &status, &result.worst_z, name) == 6) {
      result.ran = true;
      result.worst_name = name;
      (std::string(from) == "start" ? line->from_start : line->from_truth) = result;
    }
  }
  pclose(pipe);
  remove_file();
  if (!line->from_start.ran || !line->from_truth.ran) {
    line->note = "scipy_fit.py failed: " + output.substr(0, 300);
  }
}

}  // namespace

int main(int argc, char** argv) {
  int cases = 200;
  unsigned long first_seed = 1;
  bool verbose = false;
  int threads = 1;  // > 1: each case is fitted again on this many threads and compared
  unsigned search_seed = 0;
  int scipy_lines = 0;
  std::vector<RandomLineVariant> variants;
  std::string variant_name = "base";
  FitOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--verbose") {
      verbose = true;
    } else if (flag == "--cases" && i + 1 < argc) {
      cases = std::atoi(argv[++i]);
    } else if (flag == "--first-seed" && i + 1 < argc) {
      first_seed = std::strtoul(argv[++i], nullptr, 10);
    } else if (flag == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (flag == "--scipy" && i + 1 < argc) {
      scipy_lines = std::atoi(argv[++i]);
    } else if (flag == "--variant" && i + 1 < argc &&
               ParseRandomLineVariants(argv[i + 1], &variants)) {
      variant_name = argv[++i];
    } else if (flag == "--search-seed" && i + 1 < argc) {
      search_seed = static_cast<unsigned>(std::strtoul(argv[++i], nullptr, 10));
    } else if (flag == "--derivatives" && i + 1 < argc &&
               ParseDerivatives(argv[i + 1], &options.derivatives)) {
      ++i;
    } else {
      std::fprintf(stderr,
                   "usage: %s [--cases N] [--first-seed S] [--threads N] [--search-seed K] "
                   "[--variant base|drive|wide-prior|stiffness|no-pull|linear|step-load|lowpass|"
                   "fast-lowpass][+...] "
                   "[--derivatives sensitivity|forward|central] [--scipy N] [--verbose]\n",
                   argv[0]);
      return 2;
    }
  }
  if (scipy_lines > 0 && std::any_of(variants.begin(), variants.end(), [](RandomLineVariant v) {
        return v != RandomLineVariant::kBase;
      })) {
    std::fprintf(stderr, "%s: --scipy goes with --variant base only\n", argv[0]);
    return 2;
  }
  FLAGS_minloglevel = 3;  // Ceres' glog: a start that fails to simulate is data, not a message
  options.hop_seed += search_seed;
  const bool scipy = scipy_lines > 0 && SciPyAvailable();
  if (scipy) InstallTemporaryFileCleanup();
  std::vector<SciPyLine> scipy_results;

  std::vector<CaseResult> results;
  int crashed = 0;
  // With --threads N: the wall time of each case on N threads, and the cases whose result differs
  // in any bit from the one-thread fit (must be none).
  std::vector<double> parallel_walls, serial_walls;
  int parallel_differs = 0;
  for (int k = 0; k < cases; ++k) {
    const unsigned long seed = first_seed + static_cast<unsigned long>(k);
    try {
      RandomLineCase c = MakeRandomLineCase(seed, variants);
      c.config.seed += search_seed;
      CaseResult r;
      r.seed = seed;
      r.description = c.description;
      r.free = static_cast<int>(c.config.free.size());
      const auto start = std::chrono::steady_clock::now();
      const FitResult fit = Fit(c.prior, c.record, c.config, options);
      r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      r.simulations = fit.summary.simulations;
      if (threads > 1) {
        FitOptions parallel_options = options;
        parallel_options.threads = threads;
        const auto parallel_start = std::chrono::steady_clock::now();
        const FitResult parallel = Fit(c.prior, c.record, c.config, parallel_options);
        parallel_walls.push_back(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - parallel_start)
                .count());
        serial_walls.push_back(r.wall_s);
        bool same = parallel.summary.cost == fit.summary.cost &&
                    parallel.summary.verdict == fit.summary.verdict &&
                    parallel.summary.simulations == fit.summary.simulations &&
                    parallel.parameters.size() == fit.parameters.size();
        for (size_t p = 0; same && p < fit.parameters.size(); ++p) {
          same = parallel.parameters[p].value == fit.parameters[p].value &&
                 parallel.parameters[p].standard_error == fit.parameters[p].standard_error;
        }
        if (!same) ++parallel_differs;
      }
      r.cost = fit.summary.cost;
      r.verdict = Verdict(fit.summary);
      if (verbose) {
        for (const auto& w : fit.summary.warnings) std::printf("  [%lu] %s\n", seed, w.c_str());
        for (size_t i = 0; i < fit.parameters.size() && i < c.truth_values.size(); ++i) {
          const auto& e = fit.parameters[i];
          std::printf("  [%lu] %s = %.6g +- %.3g (truth %.6g, start %.6g, bounds %.4g..%.4g)%s%s\n",
                      seed, e.name.c_str(), e.value, e.standard_error, c.truth_values[i], e.start,
                      e.lower, e.upper, e.at_bound ? " AT BOUND" : "",
                      e.identifiable ? "" : " not identifiable");
        }
        for (const auto& ch : fit.channels) {
          std::printf("  [%lu] channel %s: residual/noise variance %.3f, whiteness z %.2f, %s\n",
                      seed, ch.column.c_str(), ch.chi2_ratio, ch.whiteness_z,
                      ch.noise_source.c_str());
        }
      }
      if (fit.summary.success) {
        r.scores = Score(fit, c);
        r.within = Within(r.scores);
      } else {
        r.scores.finite_se = false;
        r.scores.worst_z = std::numeric_limits<double>::quiet_NaN();
        r.scores.worst_name = "(failed: " + fit.summary.message + ")";
      }
      if (!(r.within && r.verdict == "ok")) {
        FitConfig from_truth = c.config;
        for (size_t i = 0; i < from_truth.free.size(); ++i) {
          from_truth.free[i].start = c.truth_values[i];
        }
        from_truth.scan_points = 0;
        from_truth.starts = 1;
        // Each fit estimates its own noise weights, and a cost is only comparable in the same
        // weights: the reference fit keeps the default fit's final ones.
        if (fit.summary.success) {
          for (size_t k = 0; k < from_truth.channels.size(); ++k) {
            from_truth.channels[k].weight = fit.channels[k].weight;
          }
        }
        const FitResult reference = Fit(c.prior, c.record, from_truth, options);
        r.truth_verdict = Verdict(reference.summary);
        r.truth_cost = reference.summary.success ? reference.summary.cost
                                                 : std::numeric_limits<double>::quiet_NaN();
        if (reference.summary.success) r.truth_scores = Score(reference, c);
        r.cost_at_truth = std::numeric_limits<double>::quiet_NaN();
        if (fit.summary.success) {
          std::vector<double> weights;
          for (const auto& channel : fit.channels) weights.push_back(channel.weight);
          const std::vector<Oscillogram> records{c.record};
          FitModel model(c.prior, records, c.config, weights);
          model.SetStage(1.0);
          std::vector<double> u(c.truth_values.size());
          for (size_t i = 0; i < u.size(); ++i) {
            u[i] = model.Unit(static_cast<int>(i), c.truth_values[i]);
          }
          r.cost_at_truth = model.ProjectedCost(u.data());
        }
      }
      if (scipy && k < scipy_lines && fit.summary.success) {
        SciPyLine line;
        line.seed = seed;
        line.verdict = r.verdict;
        line.within = r.within;
        line.worst_z = r.scores.worst_z;
        line.wall_s = r.wall_s;
        RunSciPy(c, fit, &line);
        if (verbose) {
          if (line.note.empty()) {
            std::printf(
                "  [%lu] SciPy from the start: %.1f s, %ld simulations, worst |z| %.3g (%s); from "
                "the truth: %.1f s, %ld simulations, worst |z| %.3g (%s)\n",
                seed, line.from_start.wall_s, line.from_start.simulations, line.from_start.worst_z,
                line.from_start.worst_name.c_str(), line.from_truth.wall_s,
                line.from_truth.simulations, line.from_truth.worst_z,
                line.from_truth.worst_name.c_str());
          } else {
            std::printf("  [%lu] SciPy not run: %s\n", seed, line.note.c_str());
          }
        }
        scipy_results.push_back(std::move(line));
      }
      if (verbose) {
        std::printf(
            "seed %lu: %s, %s, worst z %+.2f (%s), cost %.6g, %.2f s, %ld simulations, %d/%d "
            "starts at the best%s",
            seed, r.verdict.c_str(), r.within ? "within 3 SE" : "OUTSIDE 3 SE", r.scores.worst_z,
            r.scores.worst_name.c_str(), r.cost, r.wall_s, r.simulations,
            fit.summary.starts_at_best, fit.summary.starts,
            r.scores.unidentifiable ? ", some not identifiable" : "");
        if (!(r.within && r.verdict == "ok")) {
          std::printf("; from the truth: cost %.6g, worst z %+.2f (%s); cost at the truth %.6g",
                      r.truth_cost, r.truth_scores.worst_z, r.truth_scores.worst_name.c_str(),
                      r.cost_at_truth);
        }
        std::printf("\n    %s\n", r.description.c_str());
        std::fflush(stdout);
      }
      results.push_back(std::move(r));
    } catch (const std::exception& e) {
      std::printf("seed %lu CRASHED: %s\n", seed, e.what());
      std::fflush(stdout);
      ++crashed;
    }
  }

  // Summary.
  const int n = static_cast<int>(results.size());
  int good_z = 0, silent_wrong = 0, false_alarms = 0, free = 0, unidentifiable = 0;
  int rms_cases = 0, rms_count = 0, within_count = 0;
  double rms_sum = 0.0, within_sum = 0.0;
  std::map<std::string, int> verdicts;
  std::vector<double> walls;
  std::vector<long> sims;
  for (const auto& r : results) {
    const bool ok = r.verdict == "ok";
    good_z += r.within ? 1 : 0;
    silent_wrong += (ok && std::abs(r.scores.worst_z) > kWrong) ? 1 : 0;
    false_alarms += (r.within && !ok) ? 1 : 0;
    ++verdicts[r.verdict];
    free += r.free;
    unidentifiable += r.scores.unidentifiable;
    if (r.scores.finite_se && !r.scores.z.empty()) {
      ++rms_cases;
      for (double z : r.scores.z) {
        rms_sum += z * z;
        ++rms_count;
        // Without the cases outside 3 SE: the calibration of the standard errors where the fit
        // found the right minimum, which one wrong minimum would otherwise swamp.
        within_sum += r.within ? z * z : 0.0;
        within_count += r.within ? 1 : 0;
      }
    }
    walls.push_back(r.wall_s);
    sims.push_back(r.simulations);
  }
  std::sort(walls.begin(), walls.end());
  std::sort(sims.begin(), sims.end());

  std::printf("\n## Default fit on random lines (variant %s), seeds %lu–%lu\n\n",
              variant_name.c_str(), first_seed, first_seed + static_cast<unsigned long>(cases) - 1);
  std::printf("| measure | value |\n|---|---|\n");
  std::printf("| cases | %d (%d crashed) |\n", n, crashed);
  std::printf("| every identifiable parameter within 3 SE | %d (%.1f %%) |\n", good_z,
              Share(good_z, n));
  std::printf("| silent wrong answers (worst \\|z\\| > 5, verdict ok) | %d |\n", silent_wrong);
  std::printf("| false alarms (within 3 SE, verdict not ok) | %d |\n", false_alarms);
  for (const auto& [verdict, count] : verdicts) {
    std::printf("| verdict %s | %d |\n", verdict.c_str(), count);
  }
  std::printf("| RMS z (%d estimates, %d cases with finite SE) | %.2f |\n", rms_count, rms_cases,
              rms_count ? std::sqrt(rms_sum / rms_count) : 0.0);
  std::printf("| RMS z, cases within 3 SE only (%d estimates) | %.2f |\n", within_count,
              within_count ? std::sqrt(within_sum / within_count) : 0.0);
  std::printf("| free parameters flagged not identifiable | %d of %d (%.1f %%) |\n", unidentifiable,
              free, Share(unidentifiable, free));
  std::printf("| wall time per fit, s: median / 95 %% / max | %.2f / %.2f / %.2f |\n",
              Quantile(walls, 0.5), Quantile(walls, 0.95), walls.empty() ? 0.0 : walls.back());
  if (!parallel_walls.empty()) {
    double serial_total = 0.0, parallel_total = 0.0;
    for (double w : serial_walls) serial_total += w;
    for (double w : parallel_walls) parallel_total += w;
    std::sort(parallel_walls.begin(), parallel_walls.end());
    std::printf(
        "| the same fits on %d threads: median wall s / total speed-up / results "
        "differing from 1 thread | %.2f / %.2fx / %d of %zu |\n",
        threads, Quantile(parallel_walls, 0.5), serial_total / parallel_total, parallel_differs,
        parallel_walls.size());
  }
  std::printf("| simulations per fit: median / 95 %% | %ld / %ld |\n", Quantile(sims, 0.5),
              Quantile(sims, 0.95));

  std::printf(
      "\nCases not (within 3 SE and ok); \"from truth\" is the same fit started at the "
      "truth, no scan, one start:\n\n");
  std::printf(
      "| seed | verdict | worst parameter | z | cost | from truth: cost | from truth: worst "
      "\\|z\\| (parameter) | cost at the truth | line |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : results) {
    if (r.within && r.verdict == "ok") continue;
    std::printf("| %lu | %s | %s | %+.2f | %.6g | %.6g | %.2f (%s) | %.6g | %s |\n", r.seed,
                r.verdict.c_str(), r.scores.worst_name.c_str(), r.scores.worst_z, r.cost,
                r.truth_cost, std::abs(r.truth_scores.worst_z), r.truth_scores.worst_name.c_str(),
                r.cost_at_truth, r.description.c_str());
  }
  if (scipy_lines > 0 && !scipy) {
    std::printf("\nSciPy: /usr/bin/python3 has no scipy; not run.\n");
  } else if (scipy) {
    std::printf(
        "\n## SciPy least_squares (trf, 2-point Jacobian) over solve_ivp (LSODA, rtol 1e-6), one "
        "local fit, on the first %d lines\n\n|z| in MillKit's standard errors; ratio: SciPy's "
        "wall time over MillKit's whole search from the prior start.\n\n",
        scipy_lines);
    std::printf(
        "| seed | MillKit: verdict, worst \\|z\\|, wall s | SciPy from the start: wall s, runs, "
        "worst \\|z\\| | from the truth: wall s, runs, worst \\|z\\| | ratio from the start / "
        "from the truth |\n|---|---|---|---|---|\n");
    int ran = 0, start_within = 0, truth_within = 0, millkit_good = 0;
    std::vector<double> start_ratios, truth_ratios;
    for (const auto& line : scipy_results) {
      if (!line.note.empty()) {
        std::printf("| %lu | %s, %.2f, %.2f | not run: %s | | |\n", line.seed, line.verdict.c_str(),
                    std::abs(line.worst_z), line.wall_s, line.note.c_str());
        continue;
      }
      ++ran;
      start_within += line.from_start.worst_z <= kWithin ? 1 : 0;
      truth_within += line.from_truth.worst_z <= kWithin ? 1 : 0;
      millkit_good += line.within && line.verdict == "ok" ? 1 : 0;
      start_ratios.push_back(line.from_start.wall_s / line.wall_s);
      truth_ratios.push_back(line.from_truth.wall_s / line.wall_s);
      std::printf("| %lu | %s, %.2f, %.2f | %.1f, %ld, %.3g | %.1f, %ld, %.3g | %.0f / %.0f |\n",
                  line.seed, line.verdict.c_str(), std::abs(line.worst_z), line.wall_s,
                  line.from_start.wall_s, line.from_start.simulations, line.from_start.worst_z,
                  line.from_truth.wall_s, line.from_truth.simulations, line.from_truth.worst_z,
                  start_ratios.back(), truth_ratios.back());
    }
    std::sort(start_ratios.begin(), start_ratios.end());
    std::sort(truth_ratios.begin(), truth_ratios.end());
    std::printf(
        "\nOf %d lines: MillKit within 3 SE and ok %d; SciPy within 3 SE from the start %d, from "
        "the truth %d. SciPy's wall time over MillKit's, median: %.0f× from the start, %.0f× "
        "from the truth.\n",
        ran, millkit_good, start_within, truth_within, Quantile(start_ratios, 0.5),
        Quantile(truth_ratios, 0.5));
  }
  std::printf(
      "\nReproduce: bench_random_lines --cases %d --first-seed %lu --search-seed %u --variant %s "
      "--derivatives %s%s --verbose\n",
      cases, first_seed, search_seed, variant_name.c_str(), DerivativesName(options.derivatives),
      scipy_lines > 0 ? (" --scipy " + std::to_string(scipy_lines)).c_str() : "");
  return crashed > 0 ? 1 : 0;
}
