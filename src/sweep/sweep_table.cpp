#include "sweep/sweep_table.h"

#include <cmath>

#include "io/toml_section.h"

namespace millkit::sweep {
namespace {

std::string NumberCell(double value) { return std::isfinite(value) ? FormatNumber(value) : ""; }

}  // namespace

std::string QuotedCell(const std::string& text) {
  std::string cell = "\"";
  for (char c : text) {
    if (c == '"') {
      cell += "\"\"";
    } else if (c == '\n' || c == '\r') {
      cell += ' ';
    } else {
      cell += c;
    }
  }
  return cell + "\"";
}

std::string FormatSweepCsv(const driveline::Scene& scene, const SweepConfig& config,
                           const CaseList& cases, const std::vector<CaseResult>& results) {
  std::string text = "case";
  for (const auto& d : config.dimensions) text += "," + d.parameter.name;
  text += ",status,events";
  for (int l : config.links) text += ",kd." + scene.links[l].name;
  for (int l : config.links) text += ",peak_Nm." + scene.links[l].name;
  text += ",message\n";
  for (size_t c = 0; c < cases.size(); ++c) {
    const CaseResult& r = results[c];
    text += std::to_string(c);
    for (double v : cases[c]) text += "," + FormatNumber(v);
    text += r.success ? ",ok," : ",failed,";
    text += std::to_string(r.events);
    for (int l : config.links) text += "," + (r.success ? NumberCell(r.kd[l]) : "");
    for (int l : config.links) text += "," + (r.success ? NumberCell(r.peak_torque_Nm[l]) : "");
    text += "," + QuotedCell(r.message) + "\n";
  }
  return text;
}

std::vector<PlotPanel> SweepPlotPanels(const driveline::Scene& scene, const SweepConfig& config,
                                       const CaseList& cases,
                                       const std::vector<CaseResult>& results) {
  std::vector<PlotPanel> panels;
  for (size_t d = 0; d < config.dimensions.size(); ++d) {
    const auto& dimension = config.dimensions[d];
    PlotPanel panel;
    panel.title = "Kd vs " + dimension.parameter.name;
    panel.x_title = dimension.parameter.name + " (" + dimension.parameter.unit + ")";
    panel.y_title = "Kd";
    panel.log_x = dimension.scale == Scale::kLog;
    for (int l : config.links) {
      PlotSeries series;
      series.label = scene.links[l].name;
      series.style = PlotSeries::Style::kMarkers;
      for (size_t c = 0; c < cases.size(); ++c) {
        if (!results[c].success || !std::isfinite(results[c].kd[l])) continue;
        series.x.push_back(cases[c][d]);
        series.y.push_back(results[c].kd[l]);
      }
      panel.series.push_back(std::move(series));
    }
    panels.push_back(std::move(panel));
  }
  return panels;
}

}  // namespace millkit::sweep
