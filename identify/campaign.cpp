#include "millkit/identify/campaign.h"

#include <Eigen/Dense>
#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <unordered_map>

#include "io/invariant.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/io/csv.h"
#include "millkit/io/input_error.h"
#include "millkit/io/input_file.h"
#include "millkit/io/number_format.h"
#include "millkit/io/svg_plot.h"
#include "millkit/version.h"
#include "numerics/parallel_for.h"

namespace millkit::identify {
namespace {

constexpr double kSecondsPerDay = 86400.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kMaxThreads = 256;
// Points of a trend line and its band across the plot.
constexpr int kTrendSamples = 32;

// Days from 1970-01-01 to the civil date (proleptic Gregorian; H. Hinnant, "chrono-Compatible
// Low-Level Date Algorithms", days_from_civil).
long DaysFromCivil(long y, long m, long d) {
  y -= m <= 2 ? 1 : 0;
  const long era = (y >= 0 ? y : y - 399) / 400;
  const long yoe = y - era * 400;
  const long doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const long doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

int DaysInMonth(long y, long m) {
  static constexpr int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
  return m == 2 && leap ? 29 : kDays[m - 1];
}

// Reads exactly `digits` decimal digits at `at`.
bool Digits(const std::string& text, size_t* at, int digits, long* value) {
  if (*at + digits > text.size()) return false;
  long v = 0;
  for (int k = 0; k < digits; ++k) {
    const char c = text[*at + k];
    if (c < '0' || c > '9') return false;
    v = 10 * v + (c - '0');
  }
  *at += digits;
  *value = v;
  return true;
}

bool Expect(const std::string& text, size_t* at, char c) {
  if (*at >= text.size() || text[*at] != c) return false;
  ++*at;
  return true;
}

std::string Where(const std::string& source, int line, const std::string& column) {
  return source + ": line " + std::to_string(line) + ", column '" + column + "'";
}

bool IsStandName(const std::string& name) {
  if (name.empty()) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == ' ' || c == '_' || c == '-' ||
           c == '.';
  });
}

std::string Quote(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"') out += '"';
    out += c == '\n' ? ' ' : c;
  }
  return out + "\"";
}

void AppendCell(double value, std::string* text) {
  *text += ',';
  if (std::isfinite(value)) AppendNumber(value, text);
}

std::string Join(const std::vector<std::string>& parts) {
  std::string out;
  for (const auto& p : parts) out += (out.empty() ? "" : "; ") + p;
  return out;
}

using FitOutcome = CampaignFitOutcome;

// Files are read one fit at a time: libmatio is not documented to be thread-safe, and reading
// is cheap beside a fit.
std::mutex read_mutex;

FitOutcome RunOneFit(const driveline::Scene& scene, const CampaignManifest& manifest,
                     const std::vector<int>& rows, const FitOptions& fit_options) {
  FitOutcome outcome;
  outcome.rows.resize(rows.size());
  try {
    std::vector<Oscillogram> records;
    driveline::Scene fitted = scene;
    FitConfig config;
    {
      const std::lock_guard lock(read_mutex);
      for (const int r : rows) {
        const CampaignRow& row = manifest.rows[r];
        CheckInputFile(row.path);
        records.push_back(LoadOscillogram(row.path, {row.time_column}));
      }
      const CampaignRow& first = manifest.rows[rows.front()];
      config = first.config.empty() ? DefaultFitConfig(fitted, records)
                                    : LoadFitConfig(first.config, records, fitted);
    }
    ApplySetValues(config, &fitted);
    const FitResult result = Fit(fitted, records, config, fit_options);
    if (!result.summary.success) {
      outcome.reason = result.summary.message;
      return outcome;
    }
    outcome.verdict = result.summary.verdict;
    if (outcome.verdict != "ok") {
      outcome.reason = Join(result.summary.warnings);
      if (outcome.reason.empty()) outcome.reason = result.summary.message;
    }
    for (const auto& p : result.parameters) {
      FitOutcome::Estimate e;
      e.name = p.record.empty() ? p.name : p.name.substr(0, p.name.rfind('@'));
      e.unit = p.unit;
      e.value = p.value;
      e.standard_error = p.identifiable ? p.standard_error : kNaN;
      for (size_t k = 0; k < rows.size(); ++k) {
        if (p.record.empty() || p.record == records[k].source) outcome.rows[k].push_back(e);
      }
    }
  } catch (const std::exception& error) {
    outcome.verdict = "failed";
    outcome.reason = error.what();
    for (auto& r : outcome.rows) r.clear();
  }
  return outcome;
}

// Weighted least squares of value = a + b·day over the points (weights 1/SE²).
TrendLine FitTrend(const std::vector<double>& days, const std::vector<double>& values,
                   const std::vector<double>& errors) {
  TrendLine trend;
  trend.points = static_cast<int>(days.size());
  if (days.empty()) return trend;
  trend.first_day = *std::min_element(days.begin(), days.end());
  trend.last_day = *std::max_element(days.begin(), days.end());
  if (days.size() < 2 || !(trend.last_day > trend.first_day)) return trend;
  Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  for (size_t k = 0; k < days.size(); ++k) {
    const double w = 1.0 / (errors[k] * errors[k]);
    const Eigen::Vector2d x(1.0, days[k]);
    normal += w * x * x.transpose();
    rhs += w * values[k] * x;
  }
  const Eigen::Matrix2d covariance = normal.inverse();
  const Eigen::Vector2d ab = covariance * rhs;
  double chi2 = 0.0;
  for (size_t k = 0; k < days.size(); ++k) {
    const double r = (values[k] - ab(0) - ab(1) * days[k]) / errors[k];
    chi2 += r * r;
  }
  const int dof = trend.points - 2;
  trend.reduced_chi2 = dof > 0 ? chi2 / dof : kNaN;
  const double scale = dof > 0 ? std::max(1.0, trend.reduced_chi2) : 1.0;
  trend.defined = true;
  trend.value_at_epoch = ab(0);
  trend.slope_per_day = ab(1);
  trend.value_at_epoch_se = std::sqrt(scale * covariance(0, 0));
  trend.slope_se = std::sqrt(scale * covariance(1, 1));
  trend.covariance = scale * covariance(0, 1);
  return trend;
}

// The part file's columns (CampaignPartCsv).
const std::vector<std::string> kPartColumns = {
    "shard",   "fit",    "line",      "file", "time",  "stand",         "group",
    "verdict", "reason", "parameter", "unit", "value", "standard_error"};

// A number of a part file: shortest round-trip when finite, so it reads back bit for bit.
void AppendExactCell(double value, std::string* text) {
  *text += ',';
  if (std::isnan(value)) {
    *text += "nan";
  } else if (std::isinf(value)) {
    *text += value > 0 ? "inf" : "-inf";
  } else {
    AppendNumber(value, text);
  }
}

std::optional<double> ParseExactNumber(const std::string& text) {
  if (text == "nan") return kNaN;
  if (text == "inf") return std::numeric_limits<double>::infinity();
  if (text == "-inf") return -std::numeric_limits<double>::infinity();
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [at, error] = std::from_chars(text.data(), end, value);
  if (text.empty() || error != std::errc() || at != end || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

std::optional<int> ParseIndex(const std::string& text) {
  int value = 0;
  const char* end = text.data() + text.size();
  const auto [at, error] = std::from_chars(text.data(), end, value);
  if (text.empty() || error != std::errc() || at != end || value < 0) return std::nullopt;
  return value;
}

// The records of a part file: cells split at ',' outside double quotes ("" is a quote), records
// at '\n' outside quotes (a '\r' before it dropped); blank and '#' lines skipped. Cells are kept
// exactly, not trimmed: a part is read back only from what CampaignPartCsv wrote.
struct PartRecord {
  int line = 0;
  std::vector<std::string> cells;
};

std::vector<PartRecord> SplitPart(const std::string& text, const std::string& source) {
  std::vector<PartRecord> records;
  size_t at = 0;
  int line = 1;
  while (at < text.size()) {
    if (text[at] == '\n' || text[at] == '#' ||
        (text[at] == '\r' && at + 1 < text.size() && text[at + 1] == '\n')) {
      const size_t end = text.find('\n', at);
      at = end == std::string::npos ? text.size() : end + 1;
      ++line;
      continue;
    }
    PartRecord record;
    record.line = line;
    std::string cell;
    bool quoted = false;
    for (; at < text.size(); ++at) {
      const char c = text[at];
      if (quoted) {
        if (c == '"' && at + 1 < text.size() && text[at + 1] == '"') {
          cell += '"';
          ++at;
        } else if (c == '"') {
          quoted = false;
        } else {
          if (c == '\n') ++line;
          cell += c;
        }
      } else if (c == '"') {
        quoted = true;
      } else if (c == ',') {
        record.cells.push_back(std::move(cell));
        cell.clear();
      } else if (c == '\n') {
        break;
      } else if (c != '\r') {
        cell += c;
      }
    }
    if (quoted) {
      throw InputError(source + ": line " + std::to_string(record.line) +
                       ": a quote that is never closed");
    }
    record.cells.push_back(std::move(cell));
    records.push_back(std::move(record));
    ++at;
    ++line;
  }
  return records;
}
}  // namespace

std::optional<double> ParseIsoTime(const std::string& text) {
  size_t at = 0;
  long y = 0, mo = 0, d = 0, h = 0, mi = 0, s = 0;
  if (!Digits(text, &at, 4, &y) || !Expect(text, &at, '-') || !Digits(text, &at, 2, &mo) ||
      !Expect(text, &at, '-') || !Digits(text, &at, 2, &d)) {
    return std::nullopt;
  }
  if (mo < 1 || mo > 12 || d < 1 || d > DaysInMonth(y, mo)) return std::nullopt;
  double seconds = 0.0;
  long zone_minutes = 0;
  if (at < text.size()) {
    if (text[at] != 'T' && text[at] != ' ') return std::nullopt;
    ++at;
    if (!Digits(text, &at, 2, &h) || !Expect(text, &at, ':') || !Digits(text, &at, 2, &mi)) {
      return std::nullopt;
    }
    if (at < text.size() && text[at] == ':') {
      ++at;
      if (!Digits(text, &at, 2, &s)) return std::nullopt;
      if (at < text.size() && (text[at] == '.' || text[at] == ',')) {
        ++at;
        double scale = 0.1;
        const size_t begin = at;
        for (; at < text.size() && text[at] >= '0' && text[at] <= '9'; ++at, scale *= 0.1) {
          seconds += (text[at] - '0') * scale;
        }
        if (at == begin) return std::nullopt;
      }
    }
    if (h > 23 || mi > 59 || s > 59) return std::nullopt;
    if (at < text.size()) {
      if (text[at] == 'Z') {
        ++at;
      } else if (text[at] == '+' || text[at] == '-') {
        const long sign = text[at] == '+' ? 1 : -1;
        ++at;
        long zh = 0, zm = 0;
        if (!Digits(text, &at, 2, &zh)) return std::nullopt;
        if (at < text.size() && text[at] == ':') ++at;
        if (!Digits(text, &at, 2, &zm) || zh > 23 || zm > 59) return std::nullopt;
        zone_minutes = sign * (60 * zh + zm);
      } else {
        return std::nullopt;
      }
    }
  }
  if (at != text.size()) return std::nullopt;
  const double days = static_cast<double>(DaysFromCivil(y, mo, d));
  return days * kSecondsPerDay + 3600.0 * h + 60.0 * (mi - zone_minutes) + s + seconds;
}

std::vector<std::string> CampaignManifest::Inputs() const {
  std::vector<std::string> inputs = {source};
  std::set<std::string> seen;
  for (const auto& row : rows) {
    for (const std::string& path : {row.config, row.path.string()}) {
      std::error_code unreadable;  // a path that cannot be looked up is no input to protect
      if (!path.empty() && seen.insert(path).second && std::filesystem::exists(path, unreadable)) {
        inputs.push_back(path);
      }
    }
  }
  return inputs;
}

CampaignManifest LoadCampaignManifest(const std::filesystem::path& path, const std::string& config,
                                      const std::string& time_column) {
  const TextTable table = ReadTextCsv(path);
  CampaignManifest manifest;
  manifest.source = path.string();
  const std::string& source = manifest.source;
  static const std::vector<std::string> kColumns = {"file",  "time",   "stand",
                                                    "group", "config", "time_column"};
  for (size_t j = 0; j < table.columns.size(); ++j) {
    const std::string& name = table.columns[j];
    if (std::find(kColumns.begin(), kColumns.end(), name) == kColumns.end()) {
      throw InputError(Where(source, table.header_line, name) +
                       ": unknown column; a manifest has file, time, stand (required), group, "
                       "config and time_column");
    }
    if (table.Find(name) != static_cast<int>(j)) {
      throw InputError(Where(source, table.header_line, name) + ": column given twice");
    }
  }
  for (const char* required : {"file", "time", "stand"}) {
    if (table.Find(required) < 0) {
      throw InputError(source + ": line " + std::to_string(table.header_line) +
                       ": the header has no column '" + required +
                       "' (required: file, time, stand)");
    }
  }
  if (table.rows.empty()) throw InputError(source + ": no record rows after the header");
  const std::filesystem::path directory = path.parent_path();
  const auto resolve = [&](const std::string& relative) {
    const std::filesystem::path p(relative);
    return p.is_absolute() || directory.empty() ? p : directory / p;
  };
  const auto cell = [&](size_t i, const char* column) {
    const int j = table.Find(column);
    return j < 0 ? std::string() : table.rows[i][j];
  };
  for (size_t i = 0; i < table.rows.size(); ++i) {
    CampaignRow row;
    row.line = table.line_numbers[i];
    row.file = cell(i, "file");
    if (row.file.empty()) {
      throw InputError(Where(source, row.line, "file") + ": empty; give the record's path");
    }
    row.path = resolve(row.file);
    row.time = cell(i, "time");
    const auto time = ParseIsoTime(row.time);
    if (!time) {
      throw InputError(Where(source, row.line, "time") + ": '" + row.time +
                       "' is not an ISO 8601 date (2026-03-14) or date-time "
                       "(2026-03-14T08:30:00, optionally with Z or +hh:mm)");
    }
    row.time_s = *time;
    row.stand = cell(i, "stand");
    if (!IsStandName(row.stand)) {
      throw InputError(Where(source, row.line, "stand") + ": '" + row.stand +
                       "' is not a stand name (one or more letters, digits, blanks, '_', '-', "
                       "'.')");
    }
    row.group = cell(i, "group");
    const std::string row_config = cell(i, "config");
    if (!row_config.empty()) {
      row.config = resolve(row_config).string();
      std::error_code unreadable;
      if (!std::filesystem::is_regular_file(row.config, unreadable)) {
        throw InputError(Where(source, row.line, "config") + ": '" + row.config +
                         "' is not a file");
      }
    } else {
      row.config = config;
    }
    row.time_column = cell(i, "time_column");
    if (row.time_column.empty()) row.time_column = time_column;
    manifest.rows.push_back(std::move(row));
  }
  // Fits: a row alone, or every row of its stand and group, in order of the first row.
  std::map<std::pair<std::string, std::string>, int> group_fit;
  for (int r = 0; r < static_cast<int>(manifest.rows.size()); ++r) {
    const CampaignRow& row = manifest.rows[r];
    if (row.group.empty()) {
      manifest.fits.push_back({r});
      continue;
    }
    const auto [it, fresh] = group_fit.emplace(std::make_pair(row.stand, row.group),
                                               static_cast<int>(manifest.fits.size()));
    if (fresh) {
      manifest.fits.push_back({r});
      continue;
    }
    std::vector<int>& fit = manifest.fits[it->second];
    const CampaignRow& first = manifest.rows[fit.front()];
    const std::string group = "group '" + row.group + "' of stand '" + row.stand + "'";
    if (row.config != first.config) {
      throw InputError(Where(source, row.line, "config") + ": " + group +
                       " is one fit with one "
                       "config, and line " +
                       std::to_string(first.line) + " gives another");
    }
    if (row.time_column != first.time_column) {
      throw InputError(Where(source, row.line, "time_column") + ": " + group +
                       " is one fit, and line " + std::to_string(first.line) +
                       " gives another time column");
    }
    for (const int other : fit) {
      if (manifest.rows[other].path == row.path) {
        throw InputError(Where(source, row.line, "file") + ": '" + row.file + "' is already in " +
                         group + " (line " + std::to_string(manifest.rows[other].line) + ")");
      }
    }
    fit.push_back(r);
  }
  const auto earliest =
      std::min_element(manifest.rows.begin(), manifest.rows.end(),
                       [](const auto& a, const auto& b) { return a.time_s < b.time_s; });
  manifest.epoch_s = earliest->time_s;
  manifest.epoch = earliest->time;
  return manifest;
}

void CampaignOptions::Validate() const {
  if (threads < 1 || threads > kMaxThreads) {
    throw InputError::Option("CampaignOptions", "threads",
                             "must lie in [1, " + std::to_string(kMaxThreads) + "] (got " +
                                 std::to_string(threads) + ")");
  }
  fit.Validate();
}

double TrendLine::StandardErrorAt(double days) const {
  const double variance = value_at_epoch_se * value_at_epoch_se + 2.0 * days * covariance +
                          days * days * slope_se * slope_se;
  return std::sqrt(std::max(variance, 0.0));
}

double FitDay(const CampaignManifest& manifest, int fit) {
  double sum = 0.0;
  for (const int r : manifest.fits[fit]) sum += manifest.rows[r].time_s - manifest.epoch_s;
  return sum / static_cast<double>(manifest.fits[fit].size()) / kSecondsPerDay;
}

std::vector<CampaignFitOutcome> RunCampaignFits(const driveline::Scene& scene,
                                                const CampaignManifest& manifest,
                                                const std::vector<int>& fits,
                                                const CampaignOptions& options) {
  options.Validate();
  FitOptions fit_options = options.fit;
  fit_options.threads = 1;
  fit_options.progress = nullptr;
  const int fit_count = static_cast<int>(fits.size());
  std::vector<FitOutcome> outcomes(fit_count);
  std::mutex progress_mutex;
  int done = 0;
  numerics::ParallelFor(fit_count, options.threads, [&](int k, int /*worker*/) {
    outcomes[k] = RunOneFit(scene, manifest, manifest.fits.at(fits[k]), fit_options);
    if (options.progress) {
      const std::lock_guard lock(progress_mutex);
      options.progress(++done, fit_count);
    }
  });
  return outcomes;
}

CampaignResult RunCampaign(const driveline::Scene& scene, const CampaignManifest& manifest,
                           const CampaignOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  std::vector<int> all(manifest.fits.size());
  for (size_t f = 0; f < all.size(); ++f) all[f] = static_cast<int>(f);
  CampaignResult result =
      AssembleCampaign(scene, manifest, RunCampaignFits(scene, manifest, all, options));
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

CampaignResult AssembleCampaign(const driveline::Scene& scene, const CampaignManifest& manifest,
                                const std::vector<CampaignFitOutcome>& outcomes) {
  const int fit_count = static_cast<int>(manifest.fits.size());
  MILLKIT_CHECK(outcomes.size() == manifest.fits.size(), "one outcome per fit of the manifest");
  CampaignResult result;
  result.rows.resize(manifest.rows.size());
  std::map<std::string, int> column;
  for (int f = 0; f < fit_count; ++f) {
    for (size_t k = 0; k < manifest.fits[f].size(); ++k) {
      for (const auto& e : outcomes[f].rows[k]) {
        if (column.count(e.name) != 0) continue;
        column[e.name] = static_cast<int>(result.parameters.size());
        CampaignParameter p{e.name, e.unit, ""};
        const auto dot = e.name.find('.');
        if (dot != std::string::npos && scene.LinkIndex(e.name.substr(0, dot)) >= 0) {
          p.link = e.name.substr(0, dot);
        }
        result.parameters.push_back(p);
      }
    }
  }
  const size_t columns = result.parameters.size();
  for (int f = 0; f < fit_count; ++f) {
    for (size_t k = 0; k < manifest.fits[f].size(); ++k) {
      CampaignRowResult& row = result.rows[manifest.fits[f][k]];
      row.verdict = outcomes[f].verdict;
      row.reason = outcomes[f].reason;
      row.fit = f;
      row.value.assign(columns, kNaN);
      row.standard_error.assign(columns, kNaN);
      for (const auto& e : outcomes[f].rows[k]) {
        row.value[column[e.name]] = e.value;
        row.standard_error[column[e.name]] = e.standard_error;
      }
      if (row.verdict != "ok") ++result.failed_rows;
    }
  }

  // Trends: stands in manifest order; one point per ok fit (its first row holds the shared value).
  std::vector<std::string> stands;
  for (const auto& row : manifest.rows) {
    if (std::find(stands.begin(), stands.end(), row.stand) == stands.end()) {
      stands.push_back(row.stand);
    }
  }
  for (const auto& stand : stands) {
    for (size_t p = 0; p < columns; ++p) {
      if (result.parameters[p].link.empty()) continue;
      std::vector<double> days, values, errors;
      for (int f = 0; f < fit_count; ++f) {
        const int first = manifest.fits[f].front();
        const CampaignRowResult& row = result.rows[first];
        if (manifest.rows[first].stand != stand || row.verdict != "ok") continue;
        const double se = row.standard_error[p];
        if (!std::isfinite(row.value[p]) || !(se > 0.0) || !std::isfinite(se)) continue;
        days.push_back(FitDay(manifest, f));
        values.push_back(row.value[p]);
        errors.push_back(se);
      }
      TrendLine trend = FitTrend(days, values, errors);
      trend.stand = stand;
      trend.parameter = result.parameters[p].name;
      trend.unit = result.parameters[p].unit;
      trend.link = result.parameters[p].link;
      result.trends.push_back(trend);
    }
  }
  return result;
}

std::string CampaignCsv(const CampaignManifest& manifest, const CampaignResult& result) {
  std::string text = "file,time,stand,group,verdict,reason";
  for (const auto& p : result.parameters) {
    text +=
        "," + Quote(p.name + " [" + p.unit + "]") + "," + Quote(p.name + ".se [" + p.unit + "]");
  }
  text += '\n';
  for (size_t r = 0; r < manifest.rows.size(); ++r) {
    const CampaignRow& row = manifest.rows[r];
    const CampaignRowResult& out = result.rows[r];
    text += Quote(row.file) + "," + Quote(row.time) + "," + Quote(row.stand) + "," +
            Quote(row.group) + "," + out.verdict + "," + Quote(out.reason);
    for (size_t p = 0; p < result.parameters.size(); ++p) {
      AppendCell(out.value[p], &text);
      AppendCell(out.standard_error[p], &text);
    }
    text += '\n';
  }
  return text;
}

std::string CampaignTrendCsv(const CampaignManifest& manifest, const CampaignResult& result) {
  std::string text =
      "stand,parameter,unit,points,slope_per_day,slope_se_per_day,value_at_epoch,"
      "value_at_epoch_se,epoch,reduced_chi2,note\n";
  for (const auto& t : result.trends) {
    text +=
        Quote(t.stand) + "," + t.parameter + "," + Quote(t.unit) + "," + std::to_string(t.points);
    if (t.defined) {
      AppendCell(t.slope_per_day, &text);
      AppendCell(t.slope_se, &text);
      AppendCell(t.value_at_epoch, &text);
      AppendCell(t.value_at_epoch_se, &text);
    } else {
      text += ",,,,";
    }
    text += "," + Quote(manifest.epoch);
    AppendCell(t.reduced_chi2, &text);
    text += "," + Quote(t.defined ? ""
                                  : "fewer than two ok fits at distinct times with a "
                                    "standard error");
    text += '\n';
  }
  return text;
}

std::vector<std::string> CampaignLinks(const driveline::Scene& scene,
                                       const CampaignResult& result) {
  std::vector<std::string> links;
  for (const auto& link : scene.links) {
    for (const auto& p : result.parameters) {
      if (p.link == link.name) {
        links.push_back(link.name);
        break;
      }
    }
  }
  return links;
}

std::string CampaignPlotSvg(const CampaignManifest& manifest, const CampaignResult& result,
                            const std::string& link, const std::string& title) {
  std::vector<PlotPanel> panels;
  for (size_t p = 0; p < result.parameters.size(); ++p) {
    const CampaignParameter& parameter = result.parameters[p];
    if (parameter.link != link) continue;
    PlotPanel panel;
    panel.title = parameter.name;
    panel.x_title = "days since " + manifest.epoch;
    panel.y_title = parameter.name + " (" + parameter.unit + ")";
    for (const auto& trend : result.trends) {
      if (trend.parameter != parameter.name) continue;
      PlotSeries points;
      points.label = trend.stand;
      points.style = PlotSeries::Style::kMarkers;
      for (int f = 0; f < static_cast<int>(manifest.fits.size()); ++f) {
        const int first = manifest.fits[f].front();
        const CampaignRowResult& row = result.rows[first];
        if (manifest.rows[first].stand != trend.stand || row.verdict != "ok") continue;
        if (!std::isfinite(row.value[p])) continue;
        points.x.push_back(FitDay(manifest, f));
        points.y.push_back(row.value[p]);
        points.y_error.push_back(row.standard_error[p]);
      }
      panel.series.push_back(std::move(points));
      if (!trend.defined) continue;
      // The band: its upper edge, a break (NaN), its lower edge: one series, one colour.
      PlotSeries line, band;
      line.label = trend.stand + " trend";
      line.emphasis = PlotSeries::Emphasis::kFit;
      band.emphasis = PlotSeries::Emphasis::kTrace;
      band.label = trend.stand + " trend ± 1 SE";
      std::vector<double> lower;
      for (int k = 0; k <= kTrendSamples; ++k) {
        const double day = trend.first_day + (trend.last_day - trend.first_day) * k / kTrendSamples;
        const double value = trend.ValueAt(day), se = trend.StandardErrorAt(day);
        line.x.push_back(day);
        line.y.push_back(value);
        band.x.push_back(day);
        band.y.push_back(value + se);
        lower.push_back(value - se);
      }
      band.x.push_back(kNaN);
      band.y.push_back(kNaN);
      band.x.insert(band.x.end(), line.x.begin(), line.x.end());
      band.y.insert(band.y.end(), lower.begin(), lower.end());
      panel.series.push_back(std::move(band));
      panel.series.push_back(std::move(line));
    }
    panels.push_back(std::move(panel));
  }
  PlotOptions options;
  options.title = title;
  options.note_column_px = options.panel_width_px;  // one note a line: they are long
  for (const auto& trend : result.trends) {
    if (trend.link != link) continue;
    options.notes.push_back(
        trend.stand + ", " + trend.parameter + ": trend " +
        (trend.defined ? ValueWithError(trend.slope_per_day, trend.slope_se) + " " + trend.unit +
                             "/day over " + std::to_string(trend.points) + " fits, " +
                             ValueWithError(trend.value_at_epoch, trend.value_at_epoch_se) + " " +
                             trend.unit + " at day 0"
                       : "no trend (" + std::to_string(trend.points) + " ok fits)"));
  }
  return RenderSvgPlot(panels, options);
}

std::vector<int> CampaignShard::Fits(const CampaignManifest& manifest) const {
  std::vector<int> fits;
  for (int f = index - 1; f < static_cast<int>(manifest.fits.size()); f += count) {
    fits.push_back(f);
  }
  return fits;
}

std::optional<CampaignShard> ParseCampaignShard(const std::string& text) {
  const auto slash = text.find('/');
  if (slash == std::string::npos) return std::nullopt;
  const auto is_digits = [](const std::string& part) {
    return !part.empty() && part.size() <= 6 &&
           std::all_of(part.begin(), part.end(), [](char c) { return c >= '0' && c <= '9'; });
  };
  const std::string k = text.substr(0, slash), n = text.substr(slash + 1);
  if (!is_digits(k) || !is_digits(n)) return std::nullopt;
  CampaignShard shard{std::stoi(k), std::stoi(n)};
  if (shard.count < 1 || shard.index < 1 || shard.index > shard.count) return std::nullopt;
  return shard;
}

namespace {

// 64-bit FNV-1a over everything fed to it; numbers go in as their bits.
class Fingerprint {
 public:
  void Add(std::string_view text) {
    for (const char c : text) {
      hash_ ^= static_cast<unsigned char>(c);
      hash_ *= 0x100000001b3ULL;
    }
    Add(static_cast<std::uint64_t>(text.size()));  // "ab","c" is not "a","bc"
  }
  void Add(std::uint64_t value) {
    for (int byte = 0; byte < 8; ++byte) {
      hash_ ^= (value >> (8 * byte)) & 0xffU;
      hash_ *= 0x100000001b3ULL;
    }
  }
  void Add(double value) { Add(std::bit_cast<std::uint64_t>(value)); }
  void Add(int value) { Add(static_cast<std::uint64_t>(static_cast<std::int64_t>(value))); }
  std::string Hex() const {
    std::ostringstream out;
    out << std::hex;
    out.width(16);
    out.fill('0');
    out << hash_;
    return out.str();
  }

 private:
  std::uint64_t hash_ = 0xcbf29ce484222325ULL;
};

constexpr std::string_view kSettingsPrefix = "# settings ";

// The settings line of a part ("" when it has none) and its line number.
std::string PartSettings(const std::string& text, int* line) {
  size_t at = 0;
  *line = 1;
  while (at < text.size() && text[at] == '#') {
    const size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view comment(text.data() + at, end - at);
    if (comment.substr(0, kSettingsPrefix.size()) == kSettingsPrefix) {
      std::string value(comment.substr(kSettingsPrefix.size()));
      while (!value.empty() && (value.back() == '\r' || value.back() == ' ')) value.pop_back();
      return value;
    }
    at = end + 1;
    ++*line;
  }
  return "";
}

}  // namespace

std::string CampaignSettings(const driveline::Scene& scene, const CampaignManifest& manifest) {
  Fingerprint f;
  f.Add(std::string_view("millkit " MILLKIT_VERSION_STRING));
  f.Add(scene.duration_s);
  f.Add(scene.sample_rate_Hz);
  f.Add(static_cast<int>(scene.contact));
  f.Add(scene.initial_speed_rad_per_s);
  f.Add(scene.band_Hz.value_or(-1.0));
  for (const auto& mass : scene.masses) {
    f.Add(mass.name);
    f.Add(mass.inertia_kg_m2);
  }
  for (const auto& link : scene.links) {
    f.Add(link.name);
    f.Add(link.from);
    f.Add(link.to);
    f.Add(link.stiffness_Nm_per_rad);
    f.Add(link.damping_Nms_per_rad);
    f.Add(link.backlash_rad);
    f.Add(link.gap_position);
    f.Add(link.ratio);
  }
  for (const auto& source : scene.torques) {
    f.Add(source.mass);
    for (const double t : source.times_s) f.Add(t);
    for (const double v : source.values_Nm) f.Add(v);
    f.Add(static_cast<int>(source.times_s.size()));
  }
  if (scene.drive) {
    f.Add(scene.drive->mass);
    f.Add(scene.drive->speed_ref_rad_per_s);
    f.Add(scene.drive->kp);
    f.Add(scene.drive->ki);
    f.Add(scene.drive->lag_s);
    f.Add(scene.drive->limit_Nm);
  }
  std::map<std::string, std::string> configs;  // each config file's content, read once
  // A config by its content, not its path: a shard started from another directory names the
  // same file otherwise.
  for (const auto& row : manifest.rows) {
    f.Add(row.time_column);
    f.Add(static_cast<int>(row.config.empty()));
    if (row.config.empty()) continue;
    auto [found, added] = configs.try_emplace(row.config);
    if (added) {
      std::ifstream in(row.config, std::ios::binary);
      std::ostringstream text;
      text << in.rdbuf();
      found->second = in ? text.str() : std::string("(unreadable)");
    }
    f.Add(found->second);
  }
  return f.Hex();
}

std::string CampaignPartCsv(const CampaignManifest& manifest, const std::string& settings,
                            const CampaignShard& shard, const std::vector<int>& fits,
                            const std::vector<CampaignFitOutcome>& outcomes) {
  MILLKIT_CHECK(fits.size() == outcomes.size(), "one outcome per fit of the part");
  const std::string shard_text = std::to_string(shard.index) + "/" + std::to_string(shard.count);
  std::string text = "# millkit identify campaign part " + shard_text + " of " +
                     Quote(manifest.source) + ": " + std::to_string(fits.size()) + " of " +
                     std::to_string(manifest.fits.size()) + " fits (merge with --merge)\n";
  text += std::string(kSettingsPrefix) + settings + "\n";
  for (size_t j = 0; j < kPartColumns.size(); ++j) text += (j ? "," : "") + kPartColumns[j];
  text += '\n';
  for (size_t k = 0; k < fits.size(); ++k) {
    const std::vector<int>& rows = manifest.fits.at(fits[k]);
    const CampaignFitOutcome& outcome = outcomes[k];
    MILLKIT_CHECK(outcome.rows.size() == rows.size(), "one estimate list per row of the fit");
    for (size_t i = 0; i < rows.size(); ++i) {
      const CampaignRow& row = manifest.rows[rows[i]];
      const std::string prefix = Quote(shard_text) + "," + std::to_string(fits[k]) + "," +
                                 std::to_string(row.line) + "," + Quote(row.file) + "," +
                                 Quote(row.time) + "," + Quote(row.stand) + "," + Quote(row.group) +
                                 "," + Quote(outcome.verdict) + "," + Quote(outcome.reason) + ",";
      if (outcome.rows[i].empty()) text += prefix + ",,,\n";
      for (const auto& e : outcome.rows[i]) {
        text += prefix + Quote(e.name) + "," + Quote(e.unit);
        AppendExactCell(e.value, &text);
        AppendExactCell(e.standard_error, &text);
        text += '\n';
      }
    }
  }
  return text;
}

std::vector<CampaignFitOutcome> MergeCampaignParts(
    const CampaignManifest& manifest, const std::string& settings,
    const std::vector<std::pair<std::string, std::string>>& parts) {
  const size_t fit_count = manifest.fits.size();
  std::vector<CampaignFitOutcome> outcomes(fit_count);
  // Where each fit came from (part index, −1: none yet) and which rows were seen.
  std::vector<int> owner(fit_count, -1);
  std::vector<int> owner_line(fit_count, 0);
  std::vector<bool> row_seen(manifest.rows.size(), false);
  std::unordered_map<int, int> row_of_line;
  for (size_t r = 0; r < manifest.rows.size(); ++r) {
    row_of_line[manifest.rows[r].line] = static_cast<int>(r);
  }
  std::vector<int> fit_of_row(manifest.rows.size(), 0);
  for (size_t f = 0; f < fit_count; ++f) {
    for (const int r : manifest.fits[f]) fit_of_row[r] = static_cast<int>(f);
  }
  int shard_count = 0;
  std::string shard_count_source;
  for (size_t p = 0; p < parts.size(); ++p) {
    const std::string& source = parts[p].first;
    const std::vector<PartRecord> records = SplitPart(parts[p].second, source);
    if (records.empty() || records.front().cells != kPartColumns) {
      throw InputError(source + ": line " +
                       std::to_string(records.empty() ? 1 : records.front().line) +
                       ": not a campaign part (written by identify --campaign --shard k/N): the "
                       "header is not shard,fit,line,file,time,stand,group,verdict,reason,"
                       "parameter,unit,value,standard_error");
    }
    int settings_line = 0;
    const std::string part_settings = PartSettings(parts[p].second, &settings_line);
    if (part_settings.empty()) {
      throw InputError(source +
                       ": no '# settings' line before the header (a part written by an older "
                       "millkit?): fit the shard again");
    }
    if (part_settings != settings) {
      throw InputError(source + ": line " + std::to_string(settings_line) +
                       ": fitted with other settings (" + part_settings + ") than this merge's (" +
                       settings +
                       "): the scene, a fit config, a time column or the millkit version "
                       "differs; give every shard and the merge the same scene, manifest and "
                       "--config");
    }
    // A part may have no row: a shard or rank beyond the number of fits.
    std::optional<CampaignShard> part_shard;
    for (size_t k = 1; k < records.size(); ++k) {
      const PartRecord& record = records[k];
      const auto where = [&](const std::string& column) {
        return Where(source, record.line, column);
      };
      if (record.cells.size() != kPartColumns.size()) {
        throw InputError(source + ": line " + std::to_string(record.line) + ": " +
                         std::to_string(record.cells.size()) + " cells, the header has " +
                         std::to_string(kPartColumns.size()));
      }
      const auto& c = record.cells;
      const auto shard = ParseCampaignShard(c[0]);
      if (!shard) throw InputError(where("shard") + ": '" + c[0] + "' is not k/N");
      if (part_shard && (shard->index != part_shard->index || shard->count != part_shard->count)) {
        throw InputError(where("shard") + ": '" + c[0] + "', but the part's first row says " +
                         std::to_string(part_shard->index) + "/" +
                         std::to_string(part_shard->count));
      }
      part_shard = shard;
      if (shard_count == 0) {
        shard_count = shard->count;
        shard_count_source = source;
      } else if (shard->count != shard_count) {
        throw InputError(where("shard") + ": a part of " + std::to_string(shard->count) +
                         " shards, but " + shard_count_source + " is one of " +
                         std::to_string(shard_count));
      }
      const auto fit = ParseIndex(c[1]);
      if (!fit || *fit >= static_cast<int>(fit_count)) {
        throw InputError(where("fit") + ": '" + c[1] + "' is not a fit of " + manifest.source +
                         " (0 … " + std::to_string(fit_count - 1) +
                         "): a part of another manifest?");
      }
      if (*fit % shard->count != shard->index - 1) {
        throw InputError(where("fit") + ": fit " + c[1] + " is not in shard " + c[0]);
      }
      const auto line = ParseIndex(c[2]);
      const auto row_at = line ? row_of_line.find(*line) : row_of_line.end();
      if (row_at == row_of_line.end()) {
        throw InputError(where("line") + ": '" + c[2] + "' is not a record line of " +
                         manifest.source + ": a part of another manifest?");
      }
      const int r = row_at->second;
      const CampaignRow& row = manifest.rows[r];
      const std::vector<int>& fit_rows = manifest.fits[*fit];
      const auto position = std::find(fit_rows.begin(), fit_rows.end(), r);
      if (position == fit_rows.end() || c[3] != row.file || c[4] != row.time || c[5] != row.stand ||
          c[6] != row.group) {
        throw InputError(source + ": line " + std::to_string(record.line) + ": fit " + c[1] +
                         ", manifest line " + c[2] + " ('" + c[3] + "', " + c[4] + ", stand '" +
                         c[5] + "', group '" + c[6] + "') is not that of " + manifest.source +
                         " ('" + row.file + "', " + row.time + ", stand '" + row.stand +
                         "', group '" + row.group + "', fit " + std::to_string(fit_of_row[r]) +
                         "): a part of another manifest?");
      }
      if (owner[*fit] >= 0 && owner[*fit] != static_cast<int>(p)) {
        throw InputError(where("fit") + ": fit " + c[1] + " (manifest line " + c[2] +
                         ") is already in " + parts[owner[*fit]].first + " (line " +
                         std::to_string(owner_line[*fit]) + "); each fit belongs in one part");
      }
      CampaignFitOutcome& outcome = outcomes[*fit];
      if (owner[*fit] < 0) {
        owner[*fit] = static_cast<int>(p);
        owner_line[*fit] = record.line;
        outcome.verdict = c[7];
        outcome.reason = c[8];
        outcome.rows.assign(fit_rows.size(), {});
      } else if (c[7] != outcome.verdict || c[8] != outcome.reason) {
        throw InputError(where("verdict") + ": fit " + c[1] + " has another verdict or reason on " +
                         "line " + std::to_string(owner_line[*fit]));
      }
      row_seen[r] = true;
      if (c[9].empty()) continue;  // a row without estimates
      auto& estimates = outcome.rows[position - fit_rows.begin()];
      for (const auto& e : estimates) {
        if (e.name == c[9]) {
          throw InputError(where("parameter") + ": '" + c[9] + "' given twice for line " + c[2]);
        }
      }
      CampaignFitOutcome::Estimate e;
      e.name = c[9];
      e.unit = c[10];
      const auto value = ParseExactNumber(c[11]);
      if (!value) throw InputError(where("value") + ": '" + c[11] + "' is not a number");
      const auto se = ParseExactNumber(c[12]);
      if (!se) throw InputError(where("standard_error") + ": '" + c[12] + "' is not a number");
      e.value = *value;
      e.standard_error = *se;
      estimates.push_back(std::move(e));
    }
  }
  std::string given;
  for (const auto& part : parts) given += (given.empty() ? "" : ", ") + part.first;
  for (size_t f = 0; f < fit_count; ++f) {
    const CampaignRow& first = manifest.rows[manifest.fits[f].front()];
    if (owner[f] < 0) {
      throw InputError(manifest.source + ": line " + std::to_string(first.line) + " ('" +
                       first.file + "', fit " + std::to_string(f) + ") is in no part (given: " +
                       given + "); every shard 1/N … N/N must be merged");
    }
    for (const int r : manifest.fits[f]) {
      if (!row_seen[r]) {
        throw InputError(parts[owner[f]].first + ": fit " + std::to_string(f) +
                         " lacks its row of manifest line " +
                         std::to_string(manifest.rows[r].line) + " ('" + manifest.rows[r].file +
                         "')");
      }
    }
  }
  return outcomes;
}

}  // namespace millkit::identify
