#include "millkit/sweep/sweep_table.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "millkit/io/number_format.h"

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

namespace {

// A grid over two parameters: one heat map of Kd per link, all on one colour scale.
std::vector<PlotPanel> HeatMapPanels(const driveline::Scene& scene, const SweepConfig& config,
                                     const CaseList& cases,
                                     const std::vector<CaseResult>& results) {
  std::vector<double> centres[2];
  for (int d = 0; d < 2; ++d) {
    centres[d] = config.dimensions[d].GridValues();
    std::sort(centres[d].begin(), centres[d].end());
    centres[d].erase(std::unique(centres[d].begin(), centres[d].end()), centres[d].end());
  }
  const auto cell = [&](int d, double value) {
    return std::lower_bound(centres[d].begin(), centres[d].end(), value) - centres[d].begin();
  };
  double z_lo = std::numeric_limits<double>::infinity(), z_hi = -z_lo;
  for (size_t c = 0; c < cases.size(); ++c) {
    if (!results[c].success) continue;
    for (int l : config.links) {
      if (!std::isfinite(results[c].kd[l])) continue;
      z_lo = std::min(z_lo, results[c].kd[l]);
      z_hi = std::max(z_hi, results[c].kd[l]);
    }
  }
  std::vector<PlotPanel> panels;
  for (int l : config.links) {
    PlotPanel panel;
    panel.title = "Kd of " + scene.links[l].name;
    for (int d = 0; d < 2; ++d) {
      const auto& parameter = config.dimensions[d].parameter;
      (d == 0 ? panel.x_title : panel.y_title) = parameter.name + " (" + parameter.unit + ")";
    }
    panel.log_x = config.dimensions[0].scale == Scale::kLog;
    panel.log_y = config.dimensions[1].scale == Scale::kLog;
    PlotHeatMap& map = panel.heat_map;
    map.x = centres[0];
    map.y = centres[1];
    map.z.assign(map.x.size() * map.y.size(), std::numeric_limits<double>::quiet_NaN());
    map.z_title = "Kd";
    if (z_lo <= z_hi) {
      map.z_lo = z_lo;
      map.z_hi = z_hi;
    }
    for (size_t c = 0; c < cases.size(); ++c) {
      if (!results[c].success) continue;
      map.z[cell(0, cases[c][0]) * map.y.size() + cell(1, cases[c][1])] = results[c].kd[l];
    }
    panels.push_back(std::move(panel));
  }
  return panels;
}

}  // namespace

std::vector<PlotPanel> SweepPlotPanels(const driveline::Scene& scene, const SweepConfig& config,
                                       const CaseList& cases,
                                       const std::vector<CaseResult>& results) {
  const bool grid = config.method == SweepConfig::Method::kGrid;
  if (grid && config.dimensions.size() == 2) {
    return HeatMapPanels(scene, config, cases, results);
  }
  // A one-parameter grid is a curve per link; otherwise each parameter's marginal scatter.
  const bool curve = grid && config.dimensions.size() == 1;
  std::vector<PlotPanel> panels;
  for (size_t d = 0; d < config.dimensions.size(); ++d) {
    const auto& dimension = config.dimensions[d];
    PlotPanel panel;
    panel.title = "Kd vs " + dimension.parameter.name;
    panel.x_title = dimension.parameter.name + " (" + dimension.parameter.unit + ")";
    panel.y_title = "Kd";
    panel.log_x = dimension.scale == Scale::kLog;
    for (int l : config.links) {
      std::vector<std::pair<double, double>> points;
      for (size_t c = 0; c < cases.size(); ++c) {
        if (!results[c].success || !std::isfinite(results[c].kd[l])) continue;
        points.emplace_back(cases[c][d], results[c].kd[l]);
      }
      if (curve) std::sort(points.begin(), points.end());
      PlotSeries series;
      series.label = scene.links[l].name;
      series.style = curve ? PlotSeries::Style::kLineAndMarkers : PlotSeries::Style::kMarkers;
      for (const auto& [x, y] : points) {
        series.x.push_back(x);
        series.y.push_back(y);
      }
      panel.series.push_back(std::move(series));
    }
    panels.push_back(std::move(panel));
  }
  return panels;
}

}  // namespace millkit::sweep
