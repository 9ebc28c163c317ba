#include "io/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace millkit {
namespace {

constexpr double kMarginLeft = 84.0;
constexpr double kMarginRight = 190.0;  // legend column
constexpr double kMarginTop = 36.0;
constexpr double kMarginBottom = 52.0;
constexpr double kTitleHeight = 30.0;
constexpr double kMarkerRadius = 2.5;
constexpr int kTargetTicks = 6;
constexpr const char* kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e",
                                    "#9467bd", "#8c564b", "#e377c2", "#17becf"};

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string Px(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.2f", value);
  return buffer;
}

std::string TickLabel(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

// An axis maps data values to [0, 1] (log10 first on a log axis) and carries its tick values.
struct Axis {
  bool log = false;
  double lo = 0.0;  // in axis coordinates (log10 of the value on a log axis)
  double hi = 1.0;
  std::vector<double> ticks;  // data values

  bool Drawable(double v) const { return std::isfinite(v) && (!log || v > 0.0); }
  double Unit(double v) const { return ((log ? std::log10(v) : v) - lo) / (hi - lo); }
};

// 1, 2 or 5 × 10^k closest above raw.
double NiceStep(double raw) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * magnitude >= raw) return m * magnitude;
  }
  return 10.0 * magnitude;
}

Axis MakeAxis(bool log, double data_lo, double data_hi) {
  Axis axis;
  axis.log = log;
  if (!(data_lo <= data_hi)) {  // no data
    data_lo = log ? 1.0 : 0.0;
    data_hi = log ? 10.0 : 1.0;
  }
  if (log) {
    double lo = std::floor(std::log10(data_lo));
    double hi = std::ceil(std::log10(data_hi));
    if (hi <= lo) hi = lo + 1.0;
    const double every = std::max(1.0, std::ceil((hi - lo) / kTargetTicks));
    axis.lo = lo;
    axis.hi = hi;
    // Two decades or fewer: 1, 2, 5 in each decade; else decades only.
    const bool fine = hi - lo <= 2.0;
    for (double e = lo; e <= hi + 0.5; e += every) {
      for (double m : {1.0, 2.0, 5.0}) {
        if ((m == 1.0 || (fine && e < hi))) axis.ticks.push_back(m * std::pow(10.0, e));
      }
    }
    return axis;
  }
  if (data_hi == data_lo) {
    const double pad = data_lo == 0.0 ? 1.0 : 0.1 * std::abs(data_lo);
    data_lo -= pad;
    data_hi += pad;
  }
  const double step = NiceStep((data_hi - data_lo) / kTargetTicks);
  const double first = std::floor(data_lo / step);
  const double last = std::ceil(data_hi / step);
  axis.lo = first * step;
  axis.hi = last * step;
  for (double i = first; i <= last + 0.5; i += 1.0) {
    const double tick = i * step;
    axis.ticks.push_back(std::abs(tick) < 1e-9 * step ? 0.0 : tick);
  }
  return axis;
}

void RenderPanel(const PlotPanel& panel, double top, const PlotOptions& options, std::string* svg) {
  double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
  double y_lo = x_lo, y_hi = -x_lo;
  Axis probe_x, probe_y;
  probe_x.log = panel.log_x;
  probe_y.log = panel.log_y;
  for (const auto& s : panel.series) {
    if (s.x.size() != s.y.size()) {
      throw std::invalid_argument("RenderSvgPlot: series '" + s.label + "' has " +
                                  std::to_string(s.x.size()) + " x and " +
                                  std::to_string(s.y.size()) + " y values");
    }
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!probe_x.Drawable(s.x[i]) || !probe_y.Drawable(s.y[i])) continue;
      x_lo = std::min(x_lo, s.x[i]);
      x_hi = std::max(x_hi, s.x[i]);
      y_lo = std::min(y_lo, s.y[i]);
      y_hi = std::max(y_hi, s.y[i]);
    }
  }
  const bool empty = !(x_lo <= x_hi);
  const Axis ax = MakeAxis(panel.log_x, x_lo, x_hi);
  const Axis ay = MakeAxis(panel.log_y, y_lo, y_hi);

  const double left = kMarginLeft;
  const double width = options.panel_width_px - kMarginLeft - kMarginRight;
  const double plot_top = top + kMarginTop;
  const double height = options.panel_height_px - kMarginTop - kMarginBottom;
  auto px = [&](double v) { return left + ax.Unit(v) * width; };
  auto py = [&](double v) { return plot_top + (1.0 - ay.Unit(v)) * height; };

  std::string& out = *svg;
  out += "<g class=\"panel\">\n";
  if (!panel.title.empty()) {
    out += "<text x=\"" + Px(left + 0.5 * width) + "\" y=\"" + Px(top + 22.0) +
           "\" text-anchor=\"middle\" font-size=\"15\">" + Escape(panel.title) + "</text>\n";
  }
  // Grid and ticks.
  for (double t : ax.ticks) {
    const double x = px(t);
    out += "<line x1=\"" + Px(x) + "\" y1=\"" + Px(plot_top) + "\" x2=\"" + Px(x) + "\" y2=\"" +
           Px(plot_top + height) + "\" stroke=\"#e0e0e0\"/>\n";
    out += "<text x=\"" + Px(x) + "\" y=\"" + Px(plot_top + height + 16.0) +
           "\" text-anchor=\"middle\" font-size=\"11\">" + TickLabel(t) + "</text>\n";
  }
  for (double t : ay.ticks) {
    const double y = py(t);
    out += "<line x1=\"" + Px(left) + "\" y1=\"" + Px(y) + "\" x2=\"" + Px(left + width) +
           "\" y2=\"" + Px(y) + "\" stroke=\"#e0e0e0\"/>\n";
    out += "<text x=\"" + Px(left - 6.0) + "\" y=\"" + Px(y + 4.0) +
           "\" text-anchor=\"end\" font-size=\"11\">" + TickLabel(t) + "</text>\n";
  }
  out += "<rect x=\"" + Px(left) + "\" y=\"" + Px(plot_top) + "\" width=\"" + Px(width) +
         "\" height=\"" + Px(height) + "\" fill=\"none\" stroke=\"#000\"/>\n";
  out += "<text x=\"" + Px(left + 0.5 * width) + "\" y=\"" + Px(plot_top + height + 38.0) +
         "\" text-anchor=\"middle\" font-size=\"13\">" + Escape(panel.x_title) + "</text>\n";
  const std::string yx = Px(left - 62.0), yy = Px(plot_top + 0.5 * height);
  out += "<text x=\"" + yx + "\" y=\"" + yy + "\" transform=\"rotate(-90 " + yx + " " + yy +
         ")\" text-anchor=\"middle\" font-size=\"13\">" + Escape(panel.y_title) + "</text>\n";
  if (empty) {
    out += "<text x=\"" + Px(left + 0.5 * width) + "\" y=\"" + Px(plot_top + 0.5 * height) +
           "\" text-anchor=\"middle\" font-size=\"13\" fill=\"#888\">no data</text>\n";
  }

  // Series, then the legend.
  int legend_row = 0;
  for (size_t k = 0; k < panel.series.size(); ++k) {
    const PlotSeries& s = panel.series[k];
    const std::string colour = kPalette[k % std::size(kPalette)];
    const bool lines = s.style != PlotSeries::Style::kMarkers;
    const bool markers = s.style != PlotSeries::Style::kLine;
    if (lines) {
      std::string points;
      auto flush = [&] {
        if (points.find(' ') != std::string::npos) {  // at least two points
          out += "<polyline fill=\"none\" stroke=\"" + colour +
                 "\" stroke-width=\"1.5\" points=\"" + points + "\"/>\n";
        }
        points.clear();
      };
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (!ax.Drawable(s.x[i]) || !ay.Drawable(s.y[i])) {
          flush();
          continue;
        }
        if (!points.empty()) points += ' ';
        points += Px(px(s.x[i])) + "," + Px(py(s.y[i]));
      }
      flush();
    }
    if (markers) {
      out += "<g fill=\"" + colour + "\">";
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (!ax.Drawable(s.x[i]) || !ay.Drawable(s.y[i])) continue;
        out += "<circle cx=\"" + Px(px(s.x[i])) + "\" cy=\"" + Px(py(s.y[i])) + "\" r=\"" +
               Px(kMarkerRadius) + "\"/>";
      }
      out += "</g>\n";
    }
    if (s.label.empty()) continue;
    const double lx = left + width + 14.0;
    const double ly = plot_top + 10.0 + 18.0 * legend_row++;
    if (lines) {
      out += "<line x1=\"" + Px(lx) + "\" y1=\"" + Px(ly) + "\" x2=\"" + Px(lx + 22.0) +
             "\" y2=\"" + Px(ly) + "\" stroke=\"" + colour + "\" stroke-width=\"1.5\"/>\n";
    }
    if (markers) {
      out += "<circle cx=\"" + Px(lx + 11.0) + "\" cy=\"" + Px(ly) + "\" r=\"" +
             Px(kMarkerRadius + 0.5) + "\" fill=\"" + colour + "\"/>\n";
    }
    out += "<text x=\"" + Px(lx + 28.0) + "\" y=\"" + Px(ly + 4.0) + "\" font-size=\"12\">" +
           Escape(s.label) + "</text>\n";
  }
  out += "</g>\n";
}

}  // namespace

std::string RenderSvgPlot(const std::vector<PlotPanel>& panels, const PlotOptions& options) {
  const double title = options.title.empty() ? 0.0 : kTitleHeight;
  const double height = title + options.panel_height_px * static_cast<double>(panels.size());
  std::string svg = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  svg += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + Px(options.panel_width_px) +
         "\" height=\"" + Px(height) + "\" viewBox=\"0 0 " + Px(options.panel_width_px) + " " +
         Px(height) + "\" font-family=\"sans-serif\">\n";
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>\n";
  if (!options.title.empty()) {
    svg += "<text x=\"" + Px(0.5 * options.panel_width_px) +
           "\" y=\"22\" text-anchor=\"middle\" font-size=\"17\">" + Escape(options.title) +
           "</text>\n";
  }
  for (size_t p = 0; p < panels.size(); ++p) {
    RenderPanel(panels[p], title + options.panel_height_px * static_cast<double>(p), options, &svg);
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace millkit
