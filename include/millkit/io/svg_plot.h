// Line, scatter and heat-map plots as a standalone SVG document: one or more panels stacked
// vertically, each with its own axes, tick labels, axis titles and legend (or colour bar). No
// external library; the caller writes the returned text (e.g. with WriteFileAtomically).
//
// Axes: linear, or logarithmic (base 10) per axis. The range of an axis covers every finite point
// of its panel (points with a non-finite coordinate, or a non-positive one on a log axis, are
// skipped and break a line) and every heat-map cell, padded by kAxisPadding of its span on each
// side (PlotAxisFor); ticks are "nice" values inside that range. A panel with no drawable point
// is drawn empty with the note "no data".
//
// So that no series hides another: series are drawn in the order of their emphasis (traces
// first, fits last), each line series of normal emphasis gets its own dash pattern and colour,
// and each marker series its own hollow shape. Tick labels carry the digits their spacing needs.
#pragma once

#include <limits>
#include <string>
#include <vector>

namespace millkit {

struct PlotSeries {
  enum class Style { kLine, kMarkers, kLineAndMarkers };
  // kTrace: thin and light, drawn first (a measured record under its fit).
  // kNormal: 1.5 px, a dash pattern and a hollow marker shape per series.
  // kFit: solid 2.2 px line and filled markers, drawn last (the fitted line, the answer).
  // kBand: a wide translucent line drawn first (an envelope that other lines run along).
  enum class Emphasis { kTrace, kNormal, kFit, kBand };
  std::string label;  // legend text; empty: not in the legend
  std::vector<double> x;
  std::vector<double> y;  // same length as x
  Style style = Style::kLine;
  Emphasis emphasis = Emphasis::kNormal;
  // Vertical error bars ± y_error[i] about each marker (empty: none; else the length of x). A
  // non-finite or non-positive entry draws no bar at that point. The bars count in the axis range.
  std::vector<double> y_error = {};
};

// Cells coloured by value on a sequential colour scale, with a colour bar beside the panel (in
// place of the legend: series drawn over a heat map are not listed). Cell (i, j) is centred on
// (x[i], y[j]); its edges lie halfway between neighbouring centres (geometrically halfway on a log
// axis), the outer cells as wide as their inner halves. A non-finite value is a grey cell.
struct PlotHeatMap {
  std::vector<double> x;  // cell centres, strictly ascending
  std::vector<double> y;  // cell centres, strictly ascending
  std::vector<double> z;  // z[i * y.size() + j] at (x[i], y[j])
  std::string z_title;    // beside the colour bar
  // The colour scale's ends; NaN: the finite z's extremes (pass the same pair to panels that
  // should be compared on one scale).
  double z_lo = std::numeric_limits<double>::quiet_NaN();
  double z_hi = std::numeric_limits<double>::quiet_NaN();
  bool label_cells = true;  // print each cell's value where the cell is wide enough
};

struct PlotPanel {
  std::string title;
  std::string x_title;
  std::string y_title;
  bool log_x = false;
  bool log_y = false;
  PlotHeatMap heat_map;  // none when its z is empty; drawn under the series
  std::vector<PlotSeries> series;
};

struct PlotOptions {
  std::string title;  // above the first panel; none when empty
  // Text lines under the title, above the panels (e.g. fitted parameters), in as many columns of
  // note_column_px as the width holds.
  std::vector<std::string> notes;
  double note_column_px = 360.0;
  double panel_width_px = 720.0;
  double panel_height_px = 360.0;
};

// Renders the panels. Throws std::invalid_argument when a series' x and y (or y_error) differ in
// length, or a
// heat map's z is not x.size() × y.size() or its centres are not strictly ascending.
std::string RenderSvgPlot(const std::vector<PlotPanel>& panels, const PlotOptions& options = {});

// The fraction of an axis's data span added on each side.
inline constexpr double kAxisPadding = 0.03;

// An axis as the renderer draws it: its ends and ticks, in data values.
struct PlotAxis {
  double lo = 0.0;
  double hi = 1.0;
  std::vector<double> ticks;        // ascending, inside [lo, hi]
  std::vector<std::string> labels;  // one per tick
};

// The axis for data in [data_lo, data_hi] (data_lo > data_hi: no data). Linear: the span padded
// by kAxisPadding each side (±10 % of the value, or ±1 at 0, when the span is zero), ticks at
// multiples of a 1, 2 or 5 × 10^k step. Log (needs data_lo > 0): the same padding in decades,
// ticks at 1, 2, 5 × 10^k (decades only when more than 10 of those fit, 1 … 9 × 10^k when fewer
// than 3 do). Labels have the digits that tell neighbouring ticks apart, no more.
PlotAxis PlotAxisFor(double data_lo, double data_hi, bool log);

// A unit for a torque axis: the values times `factor` are in `unit`.
struct PlotUnit {
  double factor = 1.0;
  std::string unit;
};

// N·m below 1e3 N·m, kN·m below 1e6 N·m, MN·m above, by the largest |torque| shown.
PlotUnit PlotTorqueUnit(double max_abs_Nm);

}  // namespace millkit
