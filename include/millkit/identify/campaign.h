// Identification campaigns (issue 15 item 3; the user's reference is docs/identify.md,
// "Campaigns"): many records of one drive line over weeks or months, each fitted with the ordinary
// fit (millkit/identify/fit.h), tabulated, and each link parameter's drift over time fitted with a
// straight line, the wear trend.
//
// The manifest is a CSV (millkit/io/csv.h, TextTable), one row per record:
//   file         required: the record, relative to the manifest's directory (any format
//                LoadOscillogram reads)
//   time         required: ISO 8601 date or date-time of the record (ParseIsoTime)
//   stand        required: the stand (or line) the record belongs to; letters, digits, blank, '_',
//                '-', '.'
//   group        optional: rows of one stand with the same non-empty group are one fit of several
//                records (shared scene parameters, per-record bite time, gain and offset); an
//                empty cell: the record is fitted alone
//   config       optional: a fit TOML (relative to the manifest) replacing the campaign's for this
//                row; empty: the campaign's (CampaignOptions::config; none: DefaultFitConfig)
//   time_column  optional: the record's time column, replacing CampaignOptions::time_column
//
// Each fit (a row, or a group) runs on one thread; fits are shared out over
// CampaignOptions::threads (numerics/parallel_for.h) and gathered in manifest order, so every
// number is the same for any thread count. A fit that cannot be made (a record that is missing or
// unreadable, a config that does not fit the record, a start that does not simulate) is reported in
// its rows with the verdict "failed" and the reason; the campaign goes on.
//
// The trend: per stand and per link parameter (stiffness, damping, backlash, gap_position), the
// weighted least-squares line value = a + b·(t − t₀) over the fits whose verdict is ok and whose
// parameter is identifiable, weights 1/SE², t in days, t₀ the manifest's earliest record time; a
// group's shared value counts once, at the mean time of its records. The covariance of (a, b) is
// (XᵀWX)⁻¹, multiplied by χ²/(n − 2) when that exceeds 1 (points scattered beyond their standard
// errors: the line does not describe them to within their errors, and the slope's error says so).
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/identify/fit.h"

namespace millkit::identify {

// Seconds since 1970-01-01T00:00:00Z of an ISO 8601 date (YYYY-MM-DD, midnight) or date-time
// (YYYY-MM-DDThh:mm[:ss[.fff]], 'T' or one blank between, then 'Z', ±hh:mm, ±hhmm or nothing;
// without a zone the time is taken as UTC). None for anything else, or a field out of its range
// (month 1–12, day within the month, hour 0–23, minute and second 0–59).
std::optional<double> ParseIsoTime(const std::string& text);

struct CampaignRow {
  int line = 0;                // manifest line (1-based)
  std::string file;            // as written in the manifest
  std::filesystem::path path;  // the manifest's directory / file
  std::string time;            // as written
  double time_s = 0.0;         // ParseIsoTime
  std::string stand;
  std::string group;        // empty: fitted alone
  std::string config;       // fit TOML path (manifest-relative resolved); empty: DefaultFitConfig
  std::string time_column;  // empty: the record's default
};

struct CampaignManifest {
  std::string source;  // the manifest file
  std::vector<CampaignRow> rows;
  std::vector<std::vector<int>> fits;  // rows of each fit, in order of the fit's first row
  double epoch_s = 0.0;                // the earliest record time: t₀ of the trends
  std::string epoch;                   // its text as written

  // Every file the campaign reads: manifest, configs and records that exist.
  std::vector<std::string> Inputs() const;
};

// Reads and checks a manifest. `config` and `time_column` are the campaign's defaults (a row's
// cell replaces them). Throws InputError naming the manifest, line and column: a missing required
// column, an unknown or repeated column, an empty file, time or stand cell, a time that is not ISO
// 8601, a stand name with other characters, a config file that does not exist, rows of one group
// with different config or time_column, a file twice in one group, no row at all.
CampaignManifest LoadCampaignManifest(const std::filesystem::path& path, const std::string& config,
                                      const std::string& time_column);

struct CampaignOptions {
  int threads = 1;  // fits run at once, 1 … 256; each fit runs on one thread
  FitOptions fit;   // the fit's knobs (its threads and progress are not used)
  // Called from the worker threads (one at a time) after each fit with the fits done and total.
  std::function<void(int done, int total)> progress;

  // Throws InputError naming the option and its rule.
  void Validate() const;
};

// A column pair of the table: a fitted scene parameter (a per-record copy under its scene name).
struct CampaignParameter {
  std::string name;
  std::string unit;
  std::string link;  // the link it belongs to; empty for mass parameters and bite_time
};

struct CampaignRowResult {
  std::string verdict;  // the fit's verdict, or "failed" when no fit was made
  std::string reason;   // why not ok: the fit's warnings, or the error (empty when ok)
  int fit = 0;          // index into CampaignManifest::fits
  // Per CampaignResult::parameters: NaN where the fit has no such parameter or failed; the
  // standard error is NaN where the parameter is not identifiable.
  std::vector<double> value;
  std::vector<double> standard_error;
};

struct TrendLine {
  std::string stand;
  std::string parameter;
  std::string unit;
  std::string link;
  int points = 0;               // fits used
  bool defined = false;         // at least two points at distinct times
  double slope_per_day = 0.0;   // unit/day
  double slope_se = 0.0;        // unit/day
  double value_at_epoch = 0.0;  // a: the line at t₀
  double value_at_epoch_se = 0.0;
  double covariance = 0.0;    // of (a, b), for the band
  double reduced_chi2 = 0.0;  // χ²/(n − 2); NaN with two points
  double first_day = 0.0;     // the points' time span, days since t₀
  double last_day = 0.0;
  // The line's value and standard error at t₀ + days.
  double ValueAt(double days) const { return value_at_epoch + slope_per_day * days; }
  double StandardErrorAt(double days) const;
};

struct CampaignResult {
  std::vector<CampaignParameter> parameters;  // in order of first appearance
  std::vector<CampaignRowResult> rows;        // one per manifest row
  std::vector<TrendLine> trends;              // stand by stand (manifest order), then parameter
  int failed_rows = 0;                        // rows whose verdict is not ok
  double wall_time_s = 0.0;

  bool AllOk() const { return failed_rows == 0; }
};

// Fits every record (or group) of the manifest to `scene` and fits the trends. Throws InputError
// only for bad options. The same as AssembleCampaign of RunCampaignFits over every fit.
CampaignResult RunCampaign(const driveline::Scene& scene, const CampaignManifest& manifest,
                           const CampaignOptions& options);

// What one fit (a manifest row, or a group) gives its rows: the unit of work that MPI ranks and
// shards share out, and what travels between them.
struct CampaignFitOutcome {
  std::string verdict = "failed";  // as CampaignRowResult
  std::string reason;
  struct Estimate {
    std::string name;  // scene parameter name (a per-record copy under its scene name)
    std::string unit;
    double value = 0.0;
    double standard_error = 0.0;  // NaN where not identifiable
  };
  std::vector<std::vector<Estimate>> rows;  // per row of the fit, in the fit's order
};

// Runs the fits `fits` (indices into manifest.fits) over options.threads; outcomes in the order of
// `fits`. Throws InputError only for bad options.
std::vector<CampaignFitOutcome> RunCampaignFits(const driveline::Scene& scene,
                                                const CampaignManifest& manifest,
                                                const std::vector<int>& fits,
                                                const CampaignOptions& options);

// The table's columns, rows and trends from one outcome per fit (in manifest.fits order); the
// numbers depend only on the outcomes, not on where or in which order they were made.
// wall_time_s is left 0.
CampaignResult AssembleCampaign(const driveline::Scene& scene, const CampaignManifest& manifest,
                                const std::vector<CampaignFitOutcome>& outcomes);

// A share of a campaign's fits for a job array (`--shard k/N`): the fits whose index i (0-based,
// manifest order of each fit's first row) has i mod count == index − 1. `index` is 1-based, as
// Slurm's SLURM_ARRAY_TASK_ID of `--array=1-N`; the MPI rank r runs shard r + 1 of the ranks.
struct CampaignShard {
  int index = 1;  // 1 … count
  int count = 1;  // ≥ 1

  std::vector<int> Fits(const CampaignManifest& manifest) const;
};

// "k/N" with decimal 1 ≤ k ≤ N; none for anything else.
std::optional<CampaignShard> ParseCampaignShard(const std::string& text);

// What a campaign's fits depend on besides the manifest's lines and the records, as 16 hex
// digits (64-bit FNV-1a): the scene as loaded, bit for bit (every mass, link, torque knot, so
// torque tables too, and the drive), each row's fit config (its content) and time column, and
// MillKit's version. Every part carries it and the merge refuses a part with another:
// a scene, config or program that changed between the shards and the merge.
std::string CampaignSettings(const driveline::Scene& scene, const CampaignManifest& manifest);

// A partial result (docs/identify.md, "Shards"): a '#' comment line, a line
// "# settings <CampaignSettings>", then the header
// shard,fit,line,file,time,stand,group,verdict,reason,parameter,unit,value,standard_error and one
// line per estimate of each row of `fits` (one line with empty parameter, unit, value and standard
// error for a row without any), text cells quoted, numbers shortest round-trip (nan, inf, -inf
// when not finite) so they read back bit for bit. `outcomes` in the order of `fits`.
std::string CampaignPartCsv(const CampaignManifest& manifest, const std::string& settings,
                            const CampaignShard& shard, const std::vector<int>& fits,
                            const std::vector<CampaignFitOutcome>& outcomes);

// One outcome per fit of `manifest` from parts written by CampaignPartCsv: (source name, text)
// pairs. Throws InputError naming the part and its line when a part is not one (header, cell
// count, a number), was fitted with other settings than `settings` (CampaignSettings) or has
// none, its lines do not match the manifest (line, file, time, stand, group: parts of another
// manifest), its shards disagree (k/N with another N, a fit not of its shard), a fit comes in two
// parts or a parameter twice in one row, or a fit or a row of one is in no part.
std::vector<CampaignFitOutcome> MergeCampaignParts(
    const CampaignManifest& manifest, const std::string& settings,
    const std::vector<std::pair<std::string, std::string>>& parts);

// Days since the manifest's epoch of each fit: the mean of its rows' times.
double FitDay(const CampaignManifest& manifest, int fit);

// The table: file, time, stand, group, verdict, reason, then per parameter "<name> [unit]" and
// "<name>.se [unit]"; text cells quoted, numbers shortest round-trip, empty cells where there is
// no value.
std::string CampaignCsv(const CampaignManifest& manifest, const CampaignResult& result);

// The trends: stand, parameter, unit, points, slope_per_day, slope_se_per_day, value_at_epoch,
// value_at_epoch_se, epoch, reduced_chi2, note (why a trend is undefined).
std::string CampaignTrendCsv(const CampaignManifest& manifest, const CampaignResult& result);

// The links that have a parameter in the table, in scene order.
std::vector<std::string> CampaignLinks(const driveline::Scene& scene, const CampaignResult& result);

// One SVG per link: a panel per link parameter, each stand's ok values against days since the
// epoch with ± SE error bars, its trend line with a ± 1 SE band and the slope in the legend.
std::string CampaignPlotSvg(const CampaignManifest& manifest, const CampaignResult& result,
                            const std::string& link, const std::string& title);

}  // namespace millkit::identify
