#include "millkit/identify/fit_report.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "millkit/io/number_format.h"
#include "millkit/io/svg_plot.h"

namespace millkit::identify {
namespace {

// Non-finite numbers become null (JSON has no NaN).
nlohmann::json Number(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
}

// Records are told apart by label: the same file given twice is two records.
bool SeveralRecords(const FitResult& result) {
  for (const auto& c : result.channels) {
    if (c.record_label != result.channels.front().record_label) return true;
  }
  return false;
}

}  // namespace

std::string FitJson(const FitResult& result, const std::string& scene_file,
                    const std::vector<std::string>& record_files) {
  using nlohmann::json;
  json doc;
  doc["scene"] = scene_file;
  doc["records"] = record_files;
  doc["time_origins_s"] = result.time_origins_s;
  doc["times"] =
      "window, trace and plot times are record times; bite_time and the scene's torque times "
      "count from each record's time origin (time_origins_s)";
  const auto& s = result.summary;
  doc["verdict"] = s.success ? s.verdict : "failed";
  doc["warnings"] = s.warnings;
  // True only for a fit whose verdict is ok: a result that is not trusted is not a success.
  doc["success"] = s.success && s.verdict == "ok";
  if (!s.success || s.verdict == "degenerate") doc["message"] = s.message;
  json parameters = json::array();
  json not_identifiable = json::array();
  for (const auto& p : result.parameters) {
    json item = {{"name", p.name},
                 {"unit", p.unit},
                 {"value", Number(p.value)},
                 {"standard_error", Number(p.identifiable ? p.standard_error : NAN)},
                 {"start", p.start},
                 {"lower", p.lower},
                 {"upper", p.upper},
                 {"at_bound", p.at_bound},
                 {"identifiable", p.identifiable}};
    if (!p.record.empty()) item["record"] = p.record;
    if (!p.identifiable) {
      item["why_not"] = p.why_not;
      not_identifiable.push_back({{"name", p.name}, {"why", p.why_not}});
    }
    parameters.push_back(item);
  }
  doc["parameters"] = parameters;
  doc["not_identifiable"] = not_identifiable;
  json channels = json::array();
  for (const auto& c : result.channels) {
    channels.push_back({{"column", c.column},
                        {"link", c.link},
                        {"record", c.record},
                        {"unit", c.unit},
                        {"gain", Number(c.gain)},
                        {"gain_standard_error", Number(c.gain_se)},
                        {"offset", Number(c.offset)},
                        {"offset_standard_error", Number(c.offset_se)},
                        {"weight_per_unit", c.weight},
                        {"noise", Number(c.noise)},
                        {"noise_source", c.noise_source},
                        {"residual_to_noise_variance", Number(c.chi2_ratio)},
                        {"residual_whiteness_z", Number(c.whiteness_z)},
                        {"gain_at_bound", c.gain_at_bound},
                        {"offset_at_bound", c.offset_at_bound},
                        {"rms_residual", Number(c.rms_residual)},
                        {"samples", c.samples}});
  }
  doc["channels"] = channels;
  json matrix = json::array();
  for (int i = 0; i < result.correlation.rows(); ++i) {
    json row = json::array();
    for (int j = 0; j < result.correlation.cols(); ++j)
      row.push_back(Number(result.correlation(i, j)));
    matrix.push_back(row);
  }
  doc["correlation"] = {{"names", result.quantity_names}, {"matrix", matrix}};
  json minima = json::array();
  for (const auto& m : result.minima) {
    json values;
    for (size_t i = 0; i < m.values.size() && i < result.parameters.size(); ++i) {
      values[result.parameters[i].name] = m.values[i];
    }
    minima.push_back({{"cost", Number(m.cost)},
                      {"start", m.start},
                      {"iterations", m.iterations},
                      {"converged", m.converged},
                      {"values", values}});
  }
  doc["multistart"] = {{"scan_points", s.scan_points},
                       {"starts", s.starts},
                       {"starts_at_best", s.starts_at_best},
                       {"escalated", s.escalated},
                       {"minima", minima}};
  doc["summary"] = {{"ceres", s.ceres_brief},
                    {"termination", s.termination},
                    {"iterations", s.iterations},
                    {"simulations", s.simulations},
                    {"wall_time_s", s.wall_time_s},
                    {"cost", Number(s.cost)},
                    {"residuals", s.residuals},
                    {"fitted_quantities", s.fitted_quantities},
                    {"noise_scale", Number(s.noise_scale)},
                    {"standard_errors",
                     "scaled by noise_scale^2 (the residual's variance over "
                     "the record's noise); widened where the cost's profile "
                     "is flatter than its linearisation"},
                    {"reciprocal_condition", Number(s.reciprocal_condition)}};
  return doc.dump(2) + "\n";
}

std::string FitTraceCsv(const FitResult& result) {
  // Channels of one record share its window times; records follow one another, each row naming
  // its record when there are several.
  const bool several = SeveralRecords(result);
  std::vector<std::vector<const ChannelEstimate*>> by_record;
  for (const auto& c : result.channels) {
    if (by_record.empty() || by_record.back().front()->record_label != c.record_label) {
      by_record.emplace_back();
    }
    by_record.back().push_back(&c);
  }
  std::string text = several ? "record,time" : "time";
  for (const auto* c : by_record.front()) {
    text += "," + c->column + ".measured," + c->column + ".fitted," + c->column + ".residual";
  }
  text += '\n';
  const auto append = [&text](double value) { AppendNumber(value, &text); };
  for (const auto& channels : by_record) {
    const auto& time = channels.front()->time_s;
    for (size_t k = 0; k < time.size(); ++k) {
      if (several) text += channels.front()->record_label + ",";
      append(time[k]);
      for (const auto* c : channels) {
        text += ',';
        append(c->measured[k]);
        text += ',';
        append(c->fitted[k]);
        text += ',';
        append(c->fitted[k] - c->measured[k]);
      }
      text += '\n';
    }
  }
  return text;
}

std::string FitPlotSvg(const FitResult& result, const std::string& title) {
  const bool several = SeveralRecords(result);
  PlotOptions options;
  options.title = title;
  options.panel_width_px = 840.0;
  options.note_column_px = 410.0;
  options.panel_height_px = 260.0;
  const auto& s = result.summary;
  options.notes.push_back("verdict: " + (s.success ? s.verdict : std::string("failed")) +
                          ", noise scale " + ShortNumber(s.noise_scale) +
                          " (standard errors after \u00b1)");
  for (const auto& p : result.parameters) {
    std::string line = p.name + " = " +
                       ValueWithError(p.value, p.identifiable ? p.standard_error : NAN) +
                       (p.unit == "1" || p.unit.empty() ? "" : " " + p.unit);
    if (p.at_bound) line += " (at bound)";
    if (!p.identifiable) line += " (not identifiable)";
    options.notes.push_back(line);
  }
  std::vector<PlotPanel> panels;
  for (const auto& c : result.channels) {
    const std::string name = several ? c.record_label + ": " + c.column : c.column;
    double peak = 0.0;
    for (const auto* trace : {&c.measured, &c.fitted}) {
      for (double v : *trace) {
        if (std::isfinite(v)) peak = std::max(peak, std::abs(v));
      }
    }
    // A channel logged in kN·m or MN·m is drawn in its unit; one in N·m in N·m, kN·m or MN·m by
    // its magnitude.
    PlotUnit unit = PlotTorqueUnit(peak);
    if (c.unit != "N*m") {
      unit = {1.0, c.unit};
      unit.unit.replace(unit.unit.find('*'), 1, "\u00b7");  // kN*m -> kN·m, as PlotTorqueUnit
    }
    const auto scaled = [&unit](std::vector<double> values) {
      for (double& v : values) v *= unit.factor;
      return values;
    };
    options.notes.push_back(name + ": gain " + ValueWithError(c.gain, c.gain_se) + ", offset " +
                            ValueWithError(c.offset * unit.factor, c.offset_se * unit.factor) +
                            " " + unit.unit);
    PlotPanel torque;
    torque.title = name + " (link " + c.link + ")";
    torque.x_title = "time, s";
    torque.y_title = "torque, " + unit.unit;
    // The record as a thin light trace, the fit drawn over it: neither hides the other.
    torque.series.push_back({"measured", c.time_s, scaled(c.measured), PlotSeries::Style::kLine,
                             PlotSeries::Emphasis::kTrace});
    torque.series.push_back({"fitted", c.time_s, scaled(c.fitted), PlotSeries::Style::kLine,
                             PlotSeries::Emphasis::kFit});
    PlotPanel residual;
    residual.title = name + ": residual (fitted - measured), rms " +
                     ShortNumber(c.rms_residual * unit.factor) + " " + unit.unit + ", noise " +
                     ShortNumber(c.noise * unit.factor) + " " + unit.unit;
    residual.x_title = "time, s";
    residual.y_title = "residual, " + unit.unit;
    std::vector<double> r(c.fitted.size());
    for (size_t k = 0; k < r.size(); ++k) r[k] = c.fitted[k] - c.measured[k];
    residual.series.push_back({"", c.time_s, scaled(r), PlotSeries::Style::kLine});
    panels.push_back(std::move(torque));
    panels.push_back(std::move(residual));
  }
  return RenderSvgPlot(panels, options);
}

}  // namespace millkit::identify
