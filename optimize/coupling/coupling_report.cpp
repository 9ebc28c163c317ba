#include "millkit/optimize/coupling/coupling_report.h"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "millkit/io/number_format.h"
#include "millkit/sweep/sweep_table.h"

namespace millkit::coupling {
namespace {

// NaN and infinities have no JSON number: null.
nlohmann::json Number(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
}

std::string Cell(double value) { return std::isfinite(value) ? FormatNumber(value) : ""; }

nlohmann::json PointJson(const driveline::Scene& scene, const CouplingProblem& problem,
                         const CouplingPoint& point) {
  nlohmann::json json;
  for (size_t i = 0; i < problem.variables.size(); ++i) {
    json["values"][problem.variables[i].parameter.name] = point.values[i];
  }
  json["kd_max"] = Number(point.kd_max);
  json["simulation_ok"] = point.simulation.success;
  if (!point.simulation.success) json["message"] = point.simulation.message;
  if (point.simulation.success) {
    for (int l : problem.counted_links) {
      const std::string& name = scene.links[l].name;
      json["links"][name] = {{"kd", Number(point.simulation.kd[l])},
                             {"peak_torque_Nm", point.simulation.peak_torque_Nm[l]},
                             {"peak_time_s", point.simulation.peak_time_s[l]},
                             {"static_torque_Nm", point.simulation.static_torque_Nm[l]}};
    }
    json["events"] = point.simulation.events;
  }
  for (size_t k = 0; k < problem.twist_limits.size(); ++k) {
    const auto& limit = problem.twist_limits[k];
    json["twist"].push_back({{"link", scene.links[limit.link].name},
                             {"rated_torque_Nm", limit.rated_torque_Nm},
                             {"twist_rad", point.twist_rad[k]},
                             {"max_twist_rad", limit.max_twist_rad},
                             {"met", point.twist_rad[k] <= limit.max_twist_rad}});
  }
  json["lowest_frequency_Hz"] = point.lowest_frequency_Hz;
  if (problem.min_frequency_Hz) {
    json["min_frequency_Hz"] = *problem.min_frequency_Hz;
    json["frequency_met"] = point.lowest_frequency_Hz >= *problem.min_frequency_Hz;
  }
  json["constraints_met"] = point.constraints_met;
  return json;
}

}  // namespace

std::string CouplingResultJson(const driveline::Scene& scene, const CouplingProblem& problem,
                               const CouplingResult& result) {
  nlohmann::json json;
  json["scene"] = scene.file;
  json["config"] = problem.file;
  for (size_t i = 0; i < problem.variables.size(); ++i) {
    const auto& v = problem.variables[i];
    json["variables"].push_back({{"name", v.parameter.name},
                                 {"unit", v.parameter.unit},
                                 {"lower", v.lower},
                                 {"upper", v.upper},
                                 {"effective_lower", result.lower[i]},
                                 {"effective_upper", result.upper[i]},
                                 {"scale", v.scale == sweep::Scale::kLog ? "log" : "linear"}});
  }
  for (int l : problem.counted_links) json["counted_links"].push_back(scene.links[l].name);
  const CouplingSummary& s = result.summary;
  json["found"] = s.found;
  if (s.found) json["best"] = PointJson(scene, problem, result.best);
  if (result.scene) json["scene_as_given"] = PointJson(scene, problem, *result.scene);
  json["summary"] = {{"global_algorithm", s.global_algorithm},
                     {"global_result", s.global_result},
                     {"global_evaluations", s.global_evaluations},
                     {"local_algorithm", s.local_algorithm},
                     {"local_result", s.local_result},
                     {"local_evaluations", s.local_evaluations},
                     {"evaluations", s.global_evaluations + s.local_evaluations},
                     {"simulations", s.simulations},
                     {"failed_simulations", s.failed_simulations},
                     {"rejected_by_frequency_limit", s.infeasible_evaluations},
                     {"nlopt_reported_value", Number(s.nlopt_value)},
                     {"chosen_from", s.chosen_from},
                     {"recheck_difference", Number(s.recheck_difference)},
                     {"wall_time_s", s.wall_time_s},
                     {"message", s.message}};
  return json.dump(2) + "\n";
}

std::string FormatCouplingTable(const driveline::Scene& scene, const CouplingProblem& problem,
                                const CouplingResult& result) {
  std::string text;
  char line[256];
  auto column = [&](const char* name, const CouplingPoint* point) {
    std::snprintf(line, sizeof(line), "%-16s", name);
    text += line;
    if (point == nullptr) return;
    for (double v : point->values) {
      std::snprintf(line, sizeof(line), " %14.6g", v);
      text += line;
    }
    std::snprintf(line, sizeof(line), " %10.4f %10.3f %s\n", point->kd_max,
                  point->lowest_frequency_Hz, point->constraints_met ? "yes" : "NO");
    text += line;
  };
  column("", nullptr);
  for (const auto& v : problem.variables) {
    std::snprintf(line, sizeof(line), " %14s", v.parameter.name.substr(0, 14).c_str());
    text += line;
  }
  std::snprintf(line, sizeof(line), " %10s %10s %s\n", "Kd_max", "f1 Hz", "limits met");
  text += line;
  if (result.scene) column("scene as given", &*result.scene);
  if (result.summary.found) column("optimum", &result.best);
  if (result.summary.found) {
    for (size_t k = 0; k < problem.twist_limits.size(); ++k) {
      const auto& limit = problem.twist_limits[k];
      std::snprintf(line, sizeof(line), "static twist of %s at %.6g N*m: %.6g rad (limit %.6g)\n",
                    scene.links[limit.link].name.c_str(), limit.rated_torque_Nm,
                    result.best.twist_rad[k], limit.max_twist_rad);
      text += line;
    }
  }
  return text;
}

std::string FormatCurveCsv(const driveline::Scene& scene, const CouplingProblem& problem,
                           const std::vector<CurvePoint>& curve) {
  std::string text = "variable,value,status,feasible,lowest_frequency_Hz";
  for (const auto& limit : problem.twist_limits) {
    text += ",twist_rad." + scene.links[limit.link].name;
  }
  text += ",kd_max";
  for (int l : problem.counted_links) text += ",kd." + scene.links[l].name;
  text += ",message\n";
  for (const auto& c : curve) {
    const CouplingPoint& p = c.point;
    const bool ok = p.simulation.success;
    text += problem.variables[c.variable].parameter.name + "," + FormatNumber(p.values[c.variable]);
    text += ok ? ",ok," : ",failed,";
    text += (p.feasible() ? "1," : "0,") + FormatNumber(p.lowest_frequency_Hz);
    for (double twist : p.twist_rad) text += "," + FormatNumber(twist);
    text += "," + Cell(p.kd_max);
    for (int l : problem.counted_links) text += "," + (ok ? Cell(p.simulation.kd[l]) : "");
    text += "," + sweep::QuotedCell(p.simulation.message) + "\n";
  }
  return text;
}

std::vector<PlotPanel> CurvePlotPanels(const driveline::Scene& scene,
                                       const CouplingProblem& problem,
                                       const std::vector<CurvePoint>& curve,
                                       const CouplingPoint& answer) {
  std::vector<PlotPanel> panels;
  for (size_t v = 0; v < problem.variables.size(); ++v) {
    const auto& variable = problem.variables[v];
    PlotPanel panel;
    panel.title = "Kd vs " + variable.parameter.name + " (other variables at the optimum)";
    panel.x_title = variable.parameter.name + " (" + variable.parameter.unit + ")";
    panel.y_title = "Kd";
    panel.log_x = variable.scale == sweep::Scale::kLog;
    PlotSeries kd_max{"Kd max", {}, {}, PlotSeries::Style::kLine};
    std::vector<PlotSeries> links;
    for (int l : problem.counted_links) {
      links.push_back({"Kd " + scene.links[l].name, {}, {}, PlotSeries::Style::kLine});
    }
    PlotSeries broken{"limit broken", {}, {}, PlotSeries::Style::kMarkers};
    for (const auto& c : curve) {
      if (c.variable != static_cast<int>(v) || !c.point.simulation.success) continue;
      const double x = c.point.values[v];
      kd_max.x.push_back(x);
      kd_max.y.push_back(c.point.kd_max);
      for (size_t k = 0; k < links.size(); ++k) {
        links[k].x.push_back(x);
        links[k].y.push_back(c.point.simulation.kd[problem.counted_links[k]]);
      }
      if (!c.point.constraints_met) {
        broken.x.push_back(x);
        broken.y.push_back(c.point.kd_max);
      }
    }
    // Kd max runs along the largest link's line: a wide translucent band under the dashed link
    // lines, so both stay visible.
    if (links.size() > 1) {
      kd_max.emphasis = PlotSeries::Emphasis::kBand;
      panel.series.push_back(std::move(kd_max));
      for (auto& s : links) panel.series.push_back(std::move(s));
    } else {
      panel.series.push_back(std::move(kd_max));
    }
    panel.series.push_back(std::move(broken));
    panel.series.push_back({"optimum",
                            {answer.values[v]},
                            {answer.kd_max},
                            PlotSeries::Style::kMarkers,
                            PlotSeries::Emphasis::kFit});
    panels.push_back(std::move(panel));
  }
  return panels;
}

}  // namespace millkit::coupling
