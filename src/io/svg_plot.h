// Line and scatter plots as a standalone SVG document: one or more panels stacked vertically, each
// with its own axes, tick labels, axis titles and legend. No external library; the caller writes
// the returned text (e.g. with WriteFileAtomically).
//
// Axes: linear, or logarithmic (base 10) per axis. The range of an axis covers every finite point
// of its panel (points with a non-finite coordinate, or a non-positive one on a log axis, are
// skipped and break a line), widened to "nice" tick values (1, 2, 5 × 10^k; decades on log axes,
// with 2 and 5 between them when the axis spans two decades or fewer).
// A panel with no drawable point is drawn empty with the note "no data".
#pragma once

#include <string>
#include <vector>

namespace millkit {

struct PlotSeries {
  enum class Style { kLine, kMarkers, kLineAndMarkers };
  std::string label;  // legend text; empty: not in the legend
  std::vector<double> x;
  std::vector<double> y;  // same length as x
  Style style = Style::kLine;
};

struct PlotPanel {
  std::string title;
  std::string x_title;
  std::string y_title;
  bool log_x = false;
  bool log_y = false;
  std::vector<PlotSeries> series;
};

struct PlotOptions {
  std::string title;  // above the first panel; none when empty
  double panel_width_px = 720.0;
  double panel_height_px = 360.0;
};

// Renders the panels. Throws std::invalid_argument when a series' x and y differ in length.
std::string RenderSvgPlot(const std::vector<PlotPanel>& panels, const PlotOptions& options = {});

}  // namespace millkit
