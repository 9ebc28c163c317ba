// millkit identify SCENE.toml --data record.csv [--data record2.csv ...] [--config fit.toml]
//                  --out fit.json [--plot fit.svg] [--trace fit.csv]
// [mpirun -np N] millkit identify SCENE.toml --campaign manifest.csv [--config fit.toml]
//                  --out campaign.csv [--trend trend.csv] [--plot PREFIX] [--threads N]
//                  (a campaign: millkit/identify/campaign.h; the ranks share the fits out)
// millkit identify SCENE.toml --campaign manifest.csv --shard k/N --out part-k.csv
// millkit identify SCENE.toml --campaign manifest.csv --merge part-1.csv ... --out campaign.csv
//                  [--trend trend.csv] [--plot PREFIX]  (job arrays without MPI)
#include <glog/logging.h>

#include <chrono>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

#include "cli/commands.h"
#include "cli/default_threads.h"
#include "millkit/driveline/scene.h"
#include "millkit/identify/campaign.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/fit_report.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/io/atomic_file.h"
#include "millkit/io/input_error.h"
#include "millkit/io/input_file.h"
#include "millkit/io/number_format.h"
#include "millkit/io/output_files.h"
#include "millkit/io/progress_line.h"
#include "millkit/sweep/mpi_runner.h"

namespace millkit::cli {
namespace {

struct IdentifyArgs {
  std::string scene;
  std::vector<std::string> data;
  std::string campaign;
  std::string trend;
  std::string shard;               // --shard k/N
  std::vector<std::string> merge;  // --merge part files
  std::string config;
  std::string out;
  std::string plot;
  std::string trace;
  std::string time_column;
  int threads = DefaultThreads();
  bool quiet = false;
};

std::string ParameterTable(const identify::FitResult& result, bool several_records) {
  std::ostringstream out;
  out << std::left << std::setw(28) << "parameter" << std::right << std::setw(14) << "value"
      << std::setw(13) << "std. error" << std::setw(13) << "start"
      << "  unit / note\n";
  for (const auto& p : result.parameters) {
    out << std::left << std::setw(28) << p.name << std::right << std::setw(14)
        << std::setprecision(6) << p.value << std::setw(13) << std::setprecision(3);
    if (p.identifiable) {
      out << p.standard_error;
    } else {
      out << "-";
    }
    out << std::setw(13) << std::setprecision(6) << p.start << "  " << p.unit;
    if (p.at_bound) out << "  AT BOUND";
    if (!p.identifiable) out << "  NOT IDENTIFIABLE: " << p.why_not;
    out << "\n";
  }
  for (const auto& c : result.channels) {
    out << "channel " << c.column << (several_records ? "@" + c.record_label : "") << " -> "
        << c.link << ": gain " << std::setprecision(6) << c.gain << " +- " << std::setprecision(2)
        << c.gain_se << ", offset " << std::setprecision(6) << c.offset << " +- "
        << std::setprecision(2) << c.offset_se << " " << c.unit << ", rms residual "
        << std::setprecision(4) << c.rms_residual << " " << c.unit << "\n";
  }
  return out.str();
}

// The trend plot of each link: PREFIX.<link>.svg.
std::string TrendPlotPath(const std::string& prefix, const std::string& link) {
  return prefix + "." + link + ".svg";
}

// The table, trends and plots of a whole campaign, computed before the first file is written and
// committed together; then the report on stdout and stderr. Exit 3 (NotTrusted) when a row is not
// ok.
void WriteCampaign(const IdentifyArgs& args, const driveline::Scene& scene,
                   const identify::CampaignManifest& manifest,
                   const identify::CampaignResult& result, const std::string& how) {
  AtomicFile table(args.out);
  table.stream() << identify::CampaignCsv(manifest, result);
  std::optional<AtomicFile> trend_file;
  if (!args.trend.empty()) {
    trend_file.emplace(args.trend);
    trend_file->stream() << identify::CampaignTrendCsv(manifest, result);
  }
  std::vector<std::unique_ptr<AtomicFile>> plots;
  if (!args.plot.empty()) {
    for (const auto& link : identify::CampaignLinks(scene, result)) {
      plots.push_back(std::make_unique<AtomicFile>(TrendPlotPath(args.plot, link)));
      plots.back()->stream() << identify::CampaignPlotSvg(
          manifest, result, link,
          "millkit identify: " + scene.name + ", " + link + " over " +
              std::filesystem::path(manifest.source).filename().string());
    }
  }
  table.Commit();
  if (trend_file) trend_file->Commit();
  for (auto& plot : plots) plot->Commit();

  std::cout << "campaign: " << manifest.rows.size() << " records in " << manifest.fits.size()
            << " fits, " << result.failed_rows << " not ok; " << how << "\n";
  for (const auto& trend : result.trends) {
    std::cout << "trend " << trend.stand << " " << trend.parameter << ": ";
    if (trend.defined) {
      std::cout << ValueWithError(trend.slope_per_day, trend.slope_se) << " " << trend.unit
                << "/day over " << trend.points << " fits (from "
                << ValueWithError(trend.value_at_epoch, trend.value_at_epoch_se) << " "
                << trend.unit << " at " << manifest.epoch << ")\n";
    } else {
      std::cout << "none (" << trend.points << " ok fits with a standard error)\n";
    }
  }
  for (size_t r = 0; r < manifest.rows.size(); ++r) {
    const auto& row = result.rows[r];
    if (row.verdict == "ok") continue;
    std::cerr << "millkit identify: " << manifest.source << ": line " << manifest.rows[r].line
              << " (" << manifest.rows[r].file << "): " << row.verdict << ": " << row.reason
              << "\n";
  }
  if (!result.AllOk()) {
    std::cerr << "millkit identify: " << result.failed_rows << " of " << manifest.rows.size()
              << " records not ok; each is reported in its row (verdict, reason)\n";
    throw NotTrusted("identify");
  }
}

std::string ThreadsText(int threads) {
  return std::to_string(threads) + (threads == 1 ? " thread" : " threads");
}

// What every rank reads and checks before the fits.
struct CampaignInputs {
  std::optional<identify::CampaignShard> shard;
  driveline::Scene scene;
  identify::CampaignManifest manifest;
};

CampaignInputs ReadCampaignInputs(const IdentifyArgs& args, const sweep::MpiSession& mpi) {
  if (!args.trace.empty()) {
    throw InputError("option --trace: not available with --campaign (fit one record with --data)");
  }
  CampaignInputs in;
  if (!args.shard.empty()) {
    in.shard = identify::ParseCampaignShard(args.shard);
    if (!in.shard) {
      throw InputError("option --shard: '" + args.shard +
                       "' is not k/N with whole numbers 1 <= k <= N (k counts from 1, as "
                       "SLURM_ARRAY_TASK_ID of --array=1-N)");
    }
    if (!args.merge.empty()) {
      throw InputError(
          "option --shard: not with --merge (fit a shard first, then merge the parts)");
    }
    for (const auto& [option, value] : {std::pair{"--trend", args.trend}, {"--plot", args.plot}}) {
      if (!value.empty()) {
        throw InputError(std::string("option ") + option +
                         ": not with --shard (the trends need every fit: give it to --merge)");
      }
    }
  }
  if ((in.shard || !args.merge.empty()) && mpi.size() > 1) {
    throw InputError(std::string("option ") + (in.shard ? "--shard" : "--merge") +
                     ": not under mpirun with several ranks (the ranks share the fits out "
                     "themselves)");
  }
  identify::CampaignOptions options;
  options.threads = args.threads;
  options.Validate();
  in.scene = driveline::LoadScene(args.scene);
  in.manifest = identify::LoadCampaignManifest(args.campaign, args.config, args.time_column);
  // Every link's plot path is checked before the work; only links with a fitted parameter are
  // written.
  std::vector<std::string> inputs = in.manifest.Inputs();
  inputs.push_back(args.scene);
  inputs.push_back(args.config);
  inputs.insert(inputs.end(), args.merge.begin(), args.merge.end());
  std::vector<std::pair<std::string, std::string>> outputs = {{"--out", args.out},
                                                              {"--trend", args.trend}};
  if (!args.plot.empty()) {
    for (const auto& link : in.scene.links) {
      outputs.emplace_back("--plot", TrendPlotPath(args.plot, link.name));
    }
  }
  CheckOutputPaths(outputs, inputs);
  return in;
}

// `--campaign`: on every MPI rank (or alone), `--shard k/N` (a part file) or `--merge` (no fits).
void RunCampaign(const IdentifyArgs& args) {
  const auto started = std::chrono::steady_clock::now();
  const sweep::MpiSession mpi;  // every rank reads and checks the same inputs
  // A rank whose inputs fail (a file its node does not see) must not leave the others waiting in
  // the gather: every rank learns of it here and stops.
  std::optional<CampaignInputs> in;
  std::exception_ptr error;
  try {
    in.emplace(ReadCampaignInputs(args, mpi));
  } catch (...) {
    error = std::current_exception();
  }
  sweep::ThrowIfAnyRankFailed(mpi, error, "reading the campaign's inputs");
  const std::optional<identify::CampaignShard>& shard = in->shard;
  const driveline::Scene& scene = in->scene;
  const identify::CampaignManifest& manifest = in->manifest;
  identify::CampaignOptions options;
  options.threads = args.threads;
  // What the fits depend on: every part carries it, and the merge (and rank 0) checks it.
  const std::string settings = identify::CampaignSettings(scene, manifest);

  if (!args.merge.empty()) {
    std::vector<std::pair<std::string, std::string>> parts;
    parts.reserve(args.merge.size());
    for (const auto& path : args.merge) {
      CheckInputFile(path, "option --merge: '" + path + "'");
      std::ifstream in(path, std::ios::binary);
      std::ostringstream text;
      text << in.rdbuf();
      if (!in) throw InputError("option --merge: '" + path + "' cannot be read");
      parts.emplace_back(path, text.str());
    }
    identify::CampaignResult result = identify::AssembleCampaign(
        scene, manifest, identify::MergeCampaignParts(manifest, settings, parts));
    WriteCampaign(
        args, scene, manifest, result,
        "merged from " + std::to_string(parts.size()) + (parts.size() == 1 ? " part" : " parts"));
    return;
  }

  // This process's fits: a shard, an MPI rank's share, or all of them.
  const identify::CampaignShard mine =
      shard ? *shard : identify::CampaignShard{mpi.rank() + 1, mpi.size()};
  const std::vector<int> fits = mine.Fits(manifest);
  ProgressLine progress(args.quiet || !mpi.root() ? nullptr : &std::cerr, "identify campaign");
  options.progress = [&progress](int done, int total) {
    progress.Update(std::to_string(done) + " of " + std::to_string(total) + " fits done");
  };
  if (shard) {
    AtomicFile part(args.out);
    const auto outcomes = identify::RunCampaignFits(scene, manifest, fits, options);
    progress.Finish();
    part.stream() << identify::CampaignPartCsv(manifest, settings, mine, fits, outcomes);
    part.Commit();
    int not_ok = 0;
    for (const auto& outcome : outcomes) {
      if (outcome.verdict != "ok") not_ok += static_cast<int>(outcome.rows.size());
    }
    std::cout
        << "campaign shard " << args.shard << ": " << fits.size() << " of " << manifest.fits.size()
        << " fits, " << not_ok << " records not ok; "
        << FixedNumber(
               std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(), 1)
        << " s on " << ThreadsText(args.threads) << "\n";
    if (not_ok > 0) {
      std::cerr << "millkit identify: " << not_ok
                << " records of this shard not ok; each is reported in its row of " << args.out
                << "\n";
      throw NotTrusted("identify");
    }
    return;
  }

  // Every rank fits its share; rank 0 gathers the shares (as part text: numbers that read back
  // bit for bit), assembles the trends and alone writes.
  std::vector<identify::CampaignFitOutcome> outcomes;
  if (mpi.size() == 1) {
    outcomes = identify::RunCampaignFits(scene, manifest, fits, options);
  } else {
    std::string part;
    try {
      part = identify::CampaignPartCsv(manifest, settings, mine, fits,
                                       identify::RunCampaignFits(scene, manifest, fits, options));
    } catch (...) {
      error = std::current_exception();
    }
    const std::vector<std::string> shares =
        sweep::GatherBytes(mpi, part, error, "during the campaign");
    if (!mpi.root()) return;
    std::vector<std::pair<std::string, std::string>> parts;
    parts.reserve(shares.size());
    for (int r = 0; r < mpi.size(); ++r) {
      parts.emplace_back("MPI rank " + std::to_string(r), shares[r]);
    }
    outcomes = identify::MergeCampaignParts(manifest, settings, parts);
  }
  progress.Finish();
  const identify::CampaignResult result = identify::AssembleCampaign(scene, manifest, outcomes);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  WriteCampaign(
      args, scene, manifest, result,
      FixedNumber(seconds, 1) + " s on " + ThreadsText(args.threads) +
          (mpi.size() > 1 ? " per rank, " + std::to_string(mpi.size()) + " MPI ranks" : ""));
}

void RunIdentify(const IdentifyArgs& args) {
  // Ceres logs through glog; a start that fails to simulate is expected data, reported in the
  // summary, not a message on stderr.
  FLAGS_minloglevel = 3;
  if (args.data.empty() == args.campaign.empty()) {
    throw InputError(
        "give either --data (one fit of one or more records) or --campaign (a "
        "manifest of records fitted one by one)");
  }
  if (!args.campaign.empty()) {
    RunCampaign(args);
    return;
  }
  if (!args.trend.empty()) throw InputError("option --trend: only with --campaign");
  if (!args.shard.empty()) throw InputError("option --shard: only with --campaign");
  if (!args.merge.empty()) throw InputError("option --merge: only with --campaign");
  // Open every output first: an unwritable directory fails before minutes of fitting, and a failed
  // fit leaves none of them behind.
  std::vector<std::string> inputs = args.data;
  inputs.push_back(args.scene);
  inputs.push_back(args.config);
  CheckOutputPaths({{"--out", args.out}, {"--plot", args.plot}, {"--trace", args.trace}}, inputs);
  AtomicFile json_file(args.out);
  std::optional<AtomicFile> plot_file;
  std::optional<AtomicFile> trace_file;
  if (!args.plot.empty()) plot_file.emplace(args.plot);
  if (!args.trace.empty()) trace_file.emplace(args.trace);

  driveline::Scene scene = driveline::LoadScene(args.scene);
  std::vector<identify::Oscillogram> records;
  std::string record_list;
  for (const auto& path : args.data) {
    records.push_back(identify::LoadOscillogram(path, {args.time_column}));
    for (const auto& note : records.back().notes)
      std::cerr << "millkit identify: note: " << note << "\n";
    record_list += (record_list.empty() ? "" : ", ") + path;
  }
  const identify::FitConfig config = args.config.empty()
                                         ? identify::DefaultFitConfig(scene, records)
                                         : identify::LoadFitConfig(args.config, records, scene);
  identify::ApplySetValues(config, &scene);
  identify::FitOptions options;
  if (args.threads < 1 || args.threads > 256) {
    throw InputError("option --threads: must lie in [1, 256] (got " + std::to_string(args.threads) +
                     ")");
  }
  options.threads = args.threads;
  ProgressLine progress(args.quiet ? nullptr : &std::cerr, "identify");
  options.progress = [&progress](const std::string& activity, long simulations) {
    progress.Update(activity + ", " + std::to_string(simulations) + " simulations");
  };
  const auto result = identify::Fit(scene, records, config, options);
  progress.Finish();
  std::cerr << result.summary.BriefReport() << "\n";
  if (!result.summary.success) {
    throw SolverFailure(record_list + ": " + result.summary.message);
  }
  for (const auto& warning : result.summary.warnings) {
    std::cerr << "millkit identify: warning: " << warning << "\n";
  }
  json_file.stream() << identify::FitJson(result, args.scene, args.data);
  if (plot_file) {
    plot_file->stream() << identify::FitPlotSvg(
        result, "millkit identify: " + scene.name + " vs " + record_list);
  }
  if (trace_file) trace_file->stream() << identify::FitTraceCsv(result);
  json_file.Commit();
  if (plot_file) plot_file->Commit();
  if (trace_file) trace_file->Commit();
  std::cout << "scene: " << scene.name << " (" << args.scene << "), "
            << (records.size() > 1 ? "records: " : "record: ") << record_list << "\n";
  for (size_t r = 0; r < result.time_origins_s.size() && r < records.size(); ++r) {
    if (result.time_origins_s[r] == 0.0) continue;
    std::cout << "time origin: record time " << FormatNumber(result.time_origins_s[r]) << " s of "
              << records[r].source << " is the model's t = 0 (bite_time counts from it; the "
              << "window and traces are in record time)\n";
  }
  std::cout << ParameterTable(result, records.size() > 1);
  std::cerr << "millkit identify: verdict: " << result.summary.verdict << "\n";
  if (result.summary.verdict != "ok") throw NotTrusted("identify");
}

}  // namespace

void AddIdentifyCommand(CLI::App& app) {
  auto args = std::make_shared<IdentifyArgs>();
  auto* command = app.add_subcommand(
      "identify",
      "Fit damping, backlash and other scene parameters to measured torque oscillograms "
      "(Ceres); write values, standard errors, correlations, identifiability flags and a "
      "verdict (ok, misfit, ambiguous, not_converged, degenerate) as JSON. Exit 0 for ok, 3 "
      "for any other verdict (every output still written), 2 for bad input, 1 when no fit "
      "could be made. Reference: docs/identify.md");
  command->add_option("scene", args->scene, "Scene TOML file")->required();
  command->add_option("--data", args->data,
                      "Record: a table (CSV, ';' or tab separated, iba ASCII export), a "
                      "MATLAB .mat (v5 or v7.3) or a COMTRADE .cfg (docs/records.md). Give it "
                      "once per record to fit several bites together (shared scene parameters; "
                      "bite time, gain and offset per record)");
  command->add_option("--campaign", args->campaign,
                      "Campaign manifest CSV instead of --data: columns file, time (ISO 8601), "
                      "stand, optional group, config, time_column; each record (or group) fitted "
                      "on its own, one table row per record, wear trends per stand and link "
                      "(docs/identify.md#campaigns)");
  command->add_option("--time-column", args->time_column,
                      "The records' time column (or MAT variable) by name or iba signal ID "
                      "(default: the one named time, t, Time, time_s or Time [s])");
  command->add_option("--config", args->config,
                      "Fit TOML: [fit], [set], [[free]], [[channel]] (docs/identify.md; default: "
                      "damping and backlash of every link, bite_time; channels named like links)");
  command
      ->add_option("--out", args->out,
                   "Fit result JSON (written atomically); with --campaign the table CSV")
      ->required();
  command->add_option("--plot", args->plot,
                      "SVG of measured vs fitted torque and residual; with --campaign a prefix: "
                      "PREFIX.<link>.svg, each link parameter against date with the trend");
  command->add_option("--trend", args->trend,
                      "With --campaign: CSV of the trend lines (slope per day with its standard "
                      "error, per stand and link parameter)");
  command->add_option("--shard", args->shard,
                      "With --campaign: k/N, fit only the fits i (0-based, manifest order) with "
                      "i mod N = k - 1 (k counts from 1) and write a part file to --out for "
                      "--merge (job arrays without MPI; docs/identify.md#shards)");
  command->add_option("--merge", args->merge,
                      "With --campaign: the part files of every shard 1/N ... N/N; writes the "
                      "table, --trend and --plot of the whole campaign, as one run would");
  command->add_option("--trace", args->trace, "CSV of measured, fitted and residual per channel");
  command
      ->add_option("--threads", args->threads,
                   "Worker threads of the search (scan, starts, hops, probes; 1 ... 256; "
                   "default: the cores this process may use, shared among the MPI ranks on "
                   "the node); with --campaign, fits run at once (each on one thread). The "
                   "result is the same for any count")
      ->default_str(std::to_string(DefaultThreads()));
  command->add_flag("--quiet", args->quiet, "No progress line on stderr");
  command->callback([args] { RunIdentify(*args); });
}

}  // namespace millkit::cli
