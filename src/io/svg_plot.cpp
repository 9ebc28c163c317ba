#include "millkit/io/svg_plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

namespace millkit {
namespace {

constexpr double kMarginLeft = 84.0;
constexpr double kMarginRight = 190.0;  // legend column or colour bar
constexpr double kMarginTop = 36.0;
constexpr double kMarginBottom = 52.0;
constexpr double kTitleHeight = 30.0;
constexpr double kNoteLineHeight = 16.0;
constexpr double kMarkerRadius = 3.0;
constexpr int kTargetTicks = 6;
constexpr int kMaxLogTicks = 10;
constexpr int kMaxCentreTicks = 12;
constexpr size_t kManyMarkers = 300;  // a heat map's axis ticks at its cell centres up to this many
constexpr const char* kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e",
                                    "#9467bd", "#8c564b", "#e377c2", "#17becf"};
// Dash patterns of successive normal line series: solid, dashed, dotted, dash-dot, dash-dot-dot.
constexpr const char* kDashes[] = {"", "7 4", "2 3", "10 3 2 3", "6 2 1.5 2 1.5 2"};
enum class Marker { kCircle, kSquare, kTriangleUp, kDiamond, kTriangleDown, kPlus };
constexpr Marker kMarkers[] = {Marker::kCircle,  Marker::kSquare,       Marker::kTriangleUp,
                               Marker::kDiamond, Marker::kTriangleDown, Marker::kPlus};
constexpr const char* kNoValueColour = "#d9d9d9";

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

// `value` with `decimals` digits after the point, times 10^exponent written as "e<exponent>" when
// the exponent is not 0. Never "-0".
std::string Decimal(double value, int decimals, int exponent = 0) {
  const double mantissa = value / std::pow(10.0, exponent);
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%.*f", std::max(decimals, 0), mantissa);
  std::string text = buffer;
  if (text.find_first_not_of("-0.") == std::string::npos) return "0";
  if (exponent != 0) text += "e" + std::to_string(exponent);
  return text;
}

// Fixed point unless the magnitude 10^e is beyond 10^-3 … 10^5, then a shared exponent.
bool NeedsExponent(int e) { return e >= 6 || e <= -4; }

int Exponent(double value) { return static_cast<int>(std::floor(std::log10(std::abs(value)))); }

// Three significant digits (heat-map cells and centres).
std::string ThreeDigits(double value) {
  if (!std::isfinite(value)) return "";
  if (value == 0.0) return "0";
  const int e = Exponent(value);
  if (NeedsExponent(e)) return Decimal(value, 2, e);
  return Decimal(value, 2 - e);
}

// ThreeDigits without trailing zeros after the point (a heat map's cell centres: 0.04, not 0.0400).
std::string CentreLabel(double value) {
  std::string text = ThreeDigits(value);
  const auto e = text.find('e');
  std::string mantissa = text.substr(0, e);
  if (mantissa.find('.') != std::string::npos) {
    mantissa.erase(mantissa.find_last_not_of('0') + 1);
    if (mantissa.back() == '.') mantissa.pop_back();
  }
  return mantissa + (e == std::string::npos ? "" : text.substr(e));
}

// 1, 2 or 5 × 10^k closest above raw.
double NiceStep(double raw) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * magnitude >= raw * (1.0 - 1e-12)) return m * magnitude;
  }
  return 10.0 * magnitude;
}

// Linear ticks at multiples of a nice step inside [lo, hi], labelled with the step's digits.
void LinearTicks(double lo, double hi, PlotAxis* axis) {
  const double step = NiceStep((hi - lo) / kTargetTicks);
  const int step_exponent = Exponent(step);
  const int e = Exponent(std::max(std::abs(lo), std::abs(hi)));
  for (double i = std::ceil(lo / step - 1e-9); i * step <= hi + 1e-9 * step; i += 1.0) {
    const double tick = std::abs(i) < 0.5 ? 0.0 : i * step;
    axis->ticks.push_back(tick);
    axis->labels.push_back(NeedsExponent(e) ? Decimal(tick, e - step_exponent, e)
                                            : Decimal(tick, -step_exponent));
  }
}

// Log ticks at m × 10^k inside [lo, hi] for m in `mantissas`, every `every`-th decade.
void LogTicks(double lo, double hi, const std::vector<int>& mantissas, int every, PlotAxis* axis) {
  axis->ticks.clear();
  axis->labels.clear();
  const int first = static_cast<int>(std::floor(std::log10(lo)));
  const int last = static_cast<int>(std::floor(std::log10(hi)));
  for (int k = first; k <= last; ++k) {
    if ((k - first) % every != 0) continue;
    for (int m : mantissas) {
      const double tick = m * std::pow(10.0, k);
      if (tick < lo * (1.0 - 1e-12) || tick > hi * (1.0 + 1e-12)) continue;
      axis->ticks.push_back(tick);
      axis->labels.push_back(NeedsExponent(k) ? std::to_string(m) + "e" + std::to_string(k)
                                              : Decimal(tick, -k));
    }
  }
}

// Ticks inside [lo, hi] (lo < hi).
void Ticks(double lo, double hi, bool log, PlotAxis* axis) {
  axis->lo = lo;
  axis->hi = hi;
  if (!log) {
    LinearTicks(lo, hi, axis);
    return;
  }
  const double decades = std::log10(hi / lo);
  if (decades > kMaxLogTicks) {
    LogTicks(lo, hi, {1}, static_cast<int>(std::ceil(decades / kTargetTicks)), axis);
    return;
  }
  LogTicks(lo, hi, {1, 2, 5}, 1, axis);
  if (axis->ticks.size() > static_cast<size_t>(kMaxLogTicks)) LogTicks(lo, hi, {1}, 1, axis);
  if (axis->ticks.size() < 3) LogTicks(lo, hi, {1, 2, 3, 4, 5, 6, 7, 8, 9}, 1, axis);
  if (axis->ticks.size() < 3) {  // less than a third of a decade: linear steps read better
    axis->ticks.clear();
    axis->labels.clear();
    LinearTicks(lo, hi, axis);
  }
}

// An axis maps data values to [0, 1] (log10 first on a log axis).
struct Scale {
  bool log = false;
  PlotAxis axis;

  bool Drawable(double v) const { return std::isfinite(v) && (!log || v > 0.0); }
  double Coordinate(double v) const { return log ? std::log10(v) : v; }
  double Unit(double v) const {
    return (Coordinate(v) - Coordinate(axis.lo)) / (Coordinate(axis.hi) - Coordinate(axis.lo));
  }
};

// Edges of the cells centred on `centres` (ascending), in data values.
std::vector<double> CellEdges(const std::vector<double>& centres, bool log) {
  std::vector<double> c(centres.size());
  for (size_t i = 0; i < c.size(); ++i) c[i] = log ? std::log10(centres[i]) : centres[i];
  std::vector<double> edges(c.size() + 1);
  if (c.size() == 1) {
    const double half = log ? 0.05 : (c[0] == 0.0 ? 0.5 : 0.1 * std::abs(c[0]));
    edges = {c[0] - half, c[0] + half};
  } else {
    for (size_t i = 1; i < c.size(); ++i) edges[i] = 0.5 * (c[i - 1] + c[i]);
    edges.front() = c.front() - (edges[1] - c.front());
    edges.back() = c.back() + (c.back() - edges[c.size() - 1]);
  }
  if (log) {
    for (double& e : edges) e = std::pow(10.0, e);
  }
  return edges;
}

// A sequential colour scale (viridis's ends and three points between), t in [0, 1].
std::string ScaleColour(double t) {
  static constexpr std::array<std::array<double, 3>, 5> kStops = {
      {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}}};
  t = std::clamp(t, 0.0, 1.0) * (kStops.size() - 1);
  const size_t i = std::min(static_cast<size_t>(t), kStops.size() - 2);
  const double f = t - static_cast<double>(i);
  char buffer[8];
  std::snprintf(
      buffer, sizeof(buffer), "#%02x%02x%02x",
      static_cast<int>(std::lround(kStops[i][0] + f * (kStops[i + 1][0] - kStops[i][0]))),
      static_cast<int>(std::lround(kStops[i][1] + f * (kStops[i + 1][1] - kStops[i][1]))),
      static_cast<int>(std::lround(kStops[i][2] + f * (kStops[i + 1][2] - kStops[i][2]))));
  return buffer;
}

std::string MarkerShape(Marker shape, double x, double y, double r) {
  auto points = [&](std::initializer_list<std::pair<double, double>> offsets) {
    std::string text = "<polygon points=\"";
    for (const auto& [dx, dy] : offsets) text += Px(x + dx * r) + "," + Px(y + dy * r) + " ";
    text.back() = '"';
    return text + "/>";
  };
  switch (shape) {
    case Marker::kCircle:
      return "<circle cx=\"" + Px(x) + "\" cy=\"" + Px(y) + "\" r=\"" + Px(r) + "\"/>";
    case Marker::kSquare:
      return "<rect x=\"" + Px(x - 0.9 * r) + "\" y=\"" + Px(y - 0.9 * r) + "\" width=\"" +
             Px(1.8 * r) + "\" height=\"" + Px(1.8 * r) + "\"/>";
    case Marker::kTriangleUp:
      return points({{0.0, -1.2}, {1.1, 0.8}, {-1.1, 0.8}});
    case Marker::kDiamond:
      return points({{0.0, -1.3}, {1.1, 0.0}, {0.0, 1.3}, {-1.1, 0.0}});
    case Marker::kTriangleDown:
      return points({{0.0, 1.2}, {1.1, -0.8}, {-1.1, -0.8}});
    case Marker::kPlus:
      return "<path d=\"M" + Px(x - 1.2 * r) + " " + Px(y) + "H" + Px(x + 1.2 * r) + "M" + Px(x) +
             " " + Px(y - 1.2 * r) + "V" + Px(y + 1.2 * r) + "\"/>";
  }
  return "";
}

// How one series is drawn.
struct Look {
  std::string colour;
  std::string dash;  // stroke-dasharray; empty: solid
  double width = 1.5;
  double opacity = 1.0;
  Marker marker = Marker::kCircle;
  double radius = kMarkerRadius;
  bool filled = false;
  int layer = 1;  // drawn in ascending layer order

  std::string Stroke() const {
    std::string text = "fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"" + Px(width) + "\"";
    if (!dash.empty()) text += " stroke-dasharray=\"" + dash + "\"";
    if (opacity < 1.0) text += " stroke-opacity=\"" + Px(opacity) + "\"";
    return text;
  }
  std::string MarkerGroup() const {
    std::string text = "<g stroke=\"" + colour + "\" stroke-width=\"1.2\" fill=\"" +
                       (filled ? colour : std::string("none")) + "\"";
    if (opacity < 1.0) text += " opacity=\"" + Px(opacity) + "\"";
    return text + ">";
  }
};

std::vector<Look> Looks(const std::vector<PlotSeries>& series) {
  std::vector<Look> looks(series.size());
  int dash = 0, marker = 0;
  for (size_t k = 0; k < series.size(); ++k) {
    const PlotSeries& s = series[k];
    Look& look = looks[k];
    look.colour = kPalette[k % std::size(kPalette)];
    const bool markers = s.style != PlotSeries::Style::kLine;
    const bool lines = s.style != PlotSeries::Style::kMarkers;
    switch (s.emphasis) {
      case PlotSeries::Emphasis::kTrace:
        look.width = 1.0;
        look.opacity = 0.7;
        look.radius = 1.6;
        look.filled = true;
        look.layer = 0;
        break;
      case PlotSeries::Emphasis::kBand:
        look.width = 7.0;
        look.opacity = 0.3;
        look.layer = 0;
        break;
      case PlotSeries::Emphasis::kNormal:
        if (lines) look.dash = kDashes[dash++ % std::size(kDashes)];
        if (markers) look.marker = kMarkers[marker++ % std::size(kMarkers)];
        if (markers && !lines && s.x.size() > kManyMarkers) {  // a cloud: smaller and lighter
          look.radius = 2.2;
          look.opacity = 0.6;
        }
        break;
      case PlotSeries::Emphasis::kFit:
        look.width = 2.2;
        look.radius = 4.5;
        look.filled = true;
        look.marker = Marker::kDiamond;
        look.layer = 2;
        break;
    }
  }
  return looks;
}

void Text(std::string* out, double x, double y, const std::string& anchor, int size,
          const std::string& text, const std::string& extra = "") {
  *out += "<text x=\"" + Px(x) + "\" y=\"" + Px(y) + "\" text-anchor=\"" + anchor +
          "\" font-size=\"" + std::to_string(size) + "\"" + extra + ">" + Escape(text) +
          "</text>\n";
}

bool HasErrorBar(const PlotSeries& s, size_t i) {
  return i < s.y_error.size() && std::isfinite(s.y_error[i]) && s.y_error[i] > 0.0;
}

void CheckPanel(const PlotPanel& panel) {
  for (const auto& s : panel.series) {
    if (s.x.size() != s.y.size()) {
      throw std::invalid_argument("RenderSvgPlot: series '" + s.label + "' has " +
                                  std::to_string(s.x.size()) + " x and " +
                                  std::to_string(s.y.size()) + " y values");
    }
    if (!s.y_error.empty() && s.y_error.size() != s.x.size()) {
      throw std::invalid_argument("RenderSvgPlot: series '" + s.label + "' has " +
                                  std::to_string(s.x.size()) + " x values and " +
                                  std::to_string(s.y_error.size()) + " error bars");
    }
  }
  const PlotHeatMap& map = panel.heat_map;
  if (map.z.empty()) return;
  if (map.z.size() != map.x.size() * map.y.size()) {
    throw std::invalid_argument("RenderSvgPlot: panel '" + panel.title + "': heat map has " +
                                std::to_string(map.z.size()) + " values for " +
                                std::to_string(map.x.size()) + " x " +
                                std::to_string(map.y.size()) + " cells");
  }
  for (const auto* centres : {&map.x, &map.y}) {
    for (size_t i = 1; i < centres->size(); ++i) {
      if (!((*centres)[i - 1] < (*centres)[i])) {
        throw std::invalid_argument("RenderSvgPlot: panel '" + panel.title +
                                    "': heat-map cell centres are not strictly ascending");
      }
    }
  }
}

// The axis of a panel: padded data range, or exactly the cells' extent under a heat map, with
// ticks at the cell centres when there are few.
Scale PanelScale(bool log, double lo, double hi, const std::vector<double>& edges,
                 const std::vector<double>& centres) {
  Scale scale;
  scale.log = log;
  if (edges.empty()) {
    scale.axis = PlotAxisFor(lo, hi, log);
    return scale;
  }
  Ticks(std::min(lo, edges.front()), std::max(hi, edges.back()), log, &scale.axis);
  if (centres.size() <= static_cast<size_t>(kMaxCentreTicks)) {
    scale.axis.ticks = centres;
    scale.axis.labels.clear();
    for (double c : centres) scale.axis.labels.push_back(CentreLabel(c));
  }
  return scale;
}

void RenderPanel(const PlotPanel& panel, int index, double top, const PlotOptions& options,
                 std::string* svg) {
  CheckPanel(panel);
  const PlotHeatMap& map = panel.heat_map;
  const bool has_map = !map.z.empty() && !map.x.empty() && !map.y.empty();
  double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
  double y_lo = x_lo, y_hi = -x_lo;
  Scale probe_x, probe_y;
  probe_x.log = panel.log_x;
  probe_y.log = panel.log_y;
  for (const auto& s : panel.series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!probe_x.Drawable(s.x[i]) || !probe_y.Drawable(s.y[i])) continue;
      x_lo = std::min(x_lo, s.x[i]);
      x_hi = std::max(x_hi, s.x[i]);
      y_lo = std::min(y_lo, s.y[i]);
      y_hi = std::max(y_hi, s.y[i]);
      if (HasErrorBar(s, i)) {
        if (probe_y.Drawable(s.y[i] - s.y_error[i])) y_lo = std::min(y_lo, s.y[i] - s.y_error[i]);
        y_hi = std::max(y_hi, s.y[i] + s.y_error[i]);
      }
    }
  }
  std::vector<double> x_edges, y_edges;
  if (has_map) {
    x_edges = CellEdges(map.x, panel.log_x);
    y_edges = CellEdges(map.y, panel.log_y);
  }
  const bool empty = !(x_lo <= x_hi) && !has_map;
  const Scale sx = PanelScale(panel.log_x, x_lo, x_hi, x_edges, map.x);
  const Scale sy = PanelScale(panel.log_y, y_lo, y_hi, y_edges, map.y);

  const double left = kMarginLeft;
  const double width = options.panel_width_px - kMarginLeft - kMarginRight;
  const double plot_top = top + kMarginTop;
  const double height = options.panel_height_px - kMarginTop - kMarginBottom;
  auto px = [&](double v) { return left + sx.Unit(v) * width; };
  auto py = [&](double v) { return plot_top + (1.0 - sy.Unit(v)) * height; };
  const double legend_x = left + width + 14.0;

  std::string& out = *svg;
  out += "<g class=\"panel\">\n";
  if (!panel.title.empty()) Text(&out, left + 0.5 * width, top + 22.0, "middle", 15, panel.title);

  if (has_map) {
    double z_lo = map.z_lo, z_hi = map.z_hi;
    if (!std::isfinite(z_lo) || !std::isfinite(z_hi)) {
      z_lo = std::numeric_limits<double>::infinity();
      z_hi = -z_lo;
      for (double z : map.z) {
        if (!std::isfinite(z)) continue;
        z_lo = std::min(z_lo, z);
        z_hi = std::max(z_hi, z);
      }
    }
    const bool any = z_lo <= z_hi;
    auto unit_z = [&](double z) { return z_hi > z_lo ? (z - z_lo) / (z_hi - z_lo) : 0.5; };
    const size_t ny = map.y.size();
    for (size_t i = 0; i < map.x.size(); ++i) {
      for (size_t j = 0; j < ny; ++j) {
        const double z = map.z[i * ny + j];
        const double x0 = px(x_edges[i]), x1 = px(x_edges[i + 1]);
        const double y0 = py(y_edges[j + 1]), y1 = py(y_edges[j]);
        const std::string fill = std::isfinite(z) ? ScaleColour(unit_z(z)) : kNoValueColour;
        out += "<rect class=\"cell\" x=\"" + Px(x0) + "\" y=\"" + Px(y0) + "\" width=\"" +
               Px(x1 - x0) + "\" height=\"" + Px(y1 - y0) + "\" fill=\"" + fill +
               "\" stroke=\"#fff\" stroke-width=\"0.5\"/>\n";
        if (map.label_cells && std::isfinite(z) && x1 - x0 >= 36.0 && y1 - y0 >= 15.0) {
          Text(&out, 0.5 * (x0 + x1), 0.5 * (y0 + y1) + 4.0, "middle", 11, ThreeDigits(z),
               unit_z(z) < 0.6 ? " fill=\"#fff\"" : "");
        }
      }
    }
    // The colour bar and its scale, in the legend column.
    const double bar_x = legend_x + 4.0, bar_w = 14.0, bar_h = height - 28.0;
    const std::string id = "scale" + std::to_string(index);
    out += "<g class=\"colour-bar\">\n<defs><linearGradient id=\"" + id +
           "\" x1=\"0\" y1=\"1\" x2=\"0\" y2=\"0\">";
    for (int k = 0; k <= 8; ++k) {
      out += "<stop offset=\"" + Px(k / 8.0) + "\" stop-color=\"" + ScaleColour(k / 8.0) + "\"/>";
    }
    out += "</linearGradient></defs>\n";
    out += "<rect x=\"" + Px(bar_x) + "\" y=\"" + Px(plot_top) + "\" width=\"" + Px(bar_w) +
           "\" height=\"" + Px(bar_h) + "\" fill=\"url(#" + id + ")\" stroke=\"#000\"/>\n";
    if (any) {
      PlotAxis z_axis;
      if (z_hi > z_lo) {
        Ticks(z_lo, z_hi, false, &z_axis);
      } else {
        z_axis.ticks = {z_lo};
        z_axis.labels = {ThreeDigits(z_lo)};
      }
      for (size_t k = 0; k < z_axis.ticks.size(); ++k) {
        const double y = plot_top + (1.0 - unit_z(z_axis.ticks[k])) * bar_h;
        out += "<line x1=\"" + Px(bar_x + bar_w) + "\" y1=\"" + Px(y) + "\" x2=\"" +
               Px(bar_x + bar_w + 4.0) + "\" y2=\"" + Px(y) + "\" stroke=\"#000\"/>\n";
        Text(&out, bar_x + bar_w + 7.0, y + 4.0, "start", 11, z_axis.labels[k]);
      }
    }
    const std::string zx = Px(bar_x + bar_w + 60.0), zy = Px(plot_top + 0.5 * bar_h);
    out += "<text x=\"" + zx + "\" y=\"" + zy + "\" transform=\"rotate(-90 " + zx + " " + zy +
           ")\" text-anchor=\"middle\" font-size=\"13\">" + Escape(map.z_title) + "</text>\n";
    if (std::any_of(map.z.begin(), map.z.end(), [](double z) { return !std::isfinite(z); })) {
      out += "<rect x=\"" + Px(bar_x) + "\" y=\"" + Px(plot_top + height - 12.0) + "\" width=\"" +
             Px(bar_w) + "\" height=\"12\" fill=\"" + kNoValueColour + "\"/>\n";
      Text(&out, bar_x + bar_w + 7.0, plot_top + height - 2.0, "start", 11, "no value");
    }
    out += "</g>\n";
  }

  // Grid and ticks (no grid lines across a heat map: its cell borders are the grid).
  for (size_t k = 0; k < sx.axis.ticks.size(); ++k) {
    const double x = px(sx.axis.ticks[k]);
    if (!has_map) {
      out += "<line x1=\"" + Px(x) + "\" y1=\"" + Px(plot_top) + "\" x2=\"" + Px(x) + "\" y2=\"" +
             Px(plot_top + height) + "\" stroke=\"#e0e0e0\"/>\n";
    }
    out += "<line x1=\"" + Px(x) + "\" y1=\"" + Px(plot_top + height) + "\" x2=\"" + Px(x) +
           "\" y2=\"" + Px(plot_top + height + 4.0) + "\" stroke=\"#000\"/>\n";
    Text(&out, x, plot_top + height + 17.0, "middle", 11, sx.axis.labels[k]);
  }
  for (size_t k = 0; k < sy.axis.ticks.size(); ++k) {
    const double y = py(sy.axis.ticks[k]);
    if (!has_map) {
      out += "<line x1=\"" + Px(left) + "\" y1=\"" + Px(y) + "\" x2=\"" + Px(left + width) +
             "\" y2=\"" + Px(y) + "\" stroke=\"#e0e0e0\"/>\n";
    }
    out += "<line x1=\"" + Px(left - 4.0) + "\" y1=\"" + Px(y) + "\" x2=\"" + Px(left) +
           "\" y2=\"" + Px(y) + "\" stroke=\"#000\"/>\n";
    Text(&out, left - 7.0, y + 4.0, "end", 11, sy.axis.labels[k]);
  }
  out += "<rect x=\"" + Px(left) + "\" y=\"" + Px(plot_top) + "\" width=\"" + Px(width) +
         "\" height=\"" + Px(height) + "\" fill=\"none\" stroke=\"#000\"/>\n";
  Text(&out, left + 0.5 * width, plot_top + height + 38.0, "middle", 13, panel.x_title);
  const std::string yx = Px(left - 62.0), yy = Px(plot_top + 0.5 * height);
  out += "<text x=\"" + yx + "\" y=\"" + yy + "\" transform=\"rotate(-90 " + yx + " " + yy +
         ")\" text-anchor=\"middle\" font-size=\"13\">" + Escape(panel.y_title) + "</text>\n";
  if (empty)
    Text(&out, left + 0.5 * width, plot_top + 0.5 * height, "middle", 13, "no data",
         " fill=\"#888\"");

  // Series in layer order (traces and bands first, fits last), then the legend in given order.
  const std::vector<Look> looks = Looks(panel.series);
  std::vector<size_t> order(panel.series.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return looks[a].layer < looks[b].layer; });
  for (size_t k : order) {
    const PlotSeries& s = panel.series[k];
    const Look& look = looks[k];
    if (s.style != PlotSeries::Style::kMarkers) {
      std::string points;
      auto flush = [&] {
        if (points.find(' ') != std::string::npos) {  // at least two points
          out += "<polyline " + look.Stroke() + " stroke-linejoin=\"round\" points=\"" + points +
                 "\"/>\n";
        }
        points.clear();
      };
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (!sx.Drawable(s.x[i]) || !sy.Drawable(s.y[i])) {
          flush();
          continue;
        }
        if (!points.empty()) points += ' ';
        points += Px(px(s.x[i])) + "," + Px(py(s.y[i]));
      }
      flush();
    }
    if (s.style != PlotSeries::Style::kLine) {
      out += look.MarkerGroup();
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (!sx.Drawable(s.x[i]) || !sy.Drawable(s.y[i])) continue;
        out += MarkerShape(look.marker, px(s.x[i]), py(s.y[i]), look.radius);
      }
      out += "</g>\n";
      // Error bars: a vertical line with short caps (clipped to the axis on a log scale).
      std::string bars;
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (!HasErrorBar(s, i) || !sx.Drawable(s.x[i]) || !sy.Drawable(s.y[i])) continue;
        const double low = s.y[i] - s.y_error[i];
        const double x = px(s.x[i]);
        const double y0 = sy.Drawable(low) ? py(low) : plot_top + height;
        const double y1 = py(s.y[i] + s.y_error[i]);
        const double cap = look.radius + 1.0;
        bars += "M" + Px(x) + " " + Px(y0) + "V" + Px(y1) + "M" + Px(x - cap) + " " + Px(y0) + "H" +
                Px(x + cap) + "M" + Px(x - cap) + " " + Px(y1) + "H" + Px(x + cap);
      }
      if (!bars.empty()) {
        out += "<path class=\"error-bars\" fill=\"none\" stroke=\"" + look.colour +
               "\" stroke-width=\"1\" d=\"" + bars + "\"/>\n";
      }
    }
  }
  if (!has_map) {
    int legend_row = 0;
    for (size_t k = 0; k < panel.series.size(); ++k) {
      const PlotSeries& s = panel.series[k];
      if (s.label.empty()) continue;
      const Look& look = looks[k];
      const double ly = plot_top + 10.0 + 18.0 * legend_row++;
      if (s.style != PlotSeries::Style::kMarkers) {
        out += "<line x1=\"" + Px(legend_x) + "\" y1=\"" + Px(ly) + "\" x2=\"" +
               Px(legend_x + 26.0) + "\" y2=\"" + Px(ly) + "\" " + look.Stroke() + "/>\n";
      }
      if (s.style != PlotSeries::Style::kLine) {
        out += look.MarkerGroup() +
               MarkerShape(look.marker, legend_x + 13.0, ly, std::max(look.radius, 2.5)) + "</g>\n";
      }
      Text(&out, legend_x + 32.0, ly + 4.0, "start", 12, s.label);
    }
  }
  out += "</g>\n";
}

}  // namespace

PlotAxis PlotAxisFor(double data_lo, double data_hi, bool log) {
  PlotAxis axis;
  if (!(data_lo <= data_hi)) {  // no data
    Ticks(log ? 1.0 : 0.0, log ? 10.0 : 1.0, log, &axis);
    return axis;
  }
  double lo = log ? std::log10(data_lo) : data_lo;
  double hi = log ? std::log10(data_hi) : data_hi;
  if (hi == lo) {
    const double half = log ? 0.05 : (lo == 0.0 ? 1.0 : 0.1 * std::abs(lo));
    lo -= half;
    hi += half;
  } else {
    const double pad = kAxisPadding * (hi - lo);
    lo -= pad;
    hi += pad;
  }
  if (log) {
    lo = std::pow(10.0, lo);
    hi = std::pow(10.0, hi);
  }
  Ticks(lo, hi, log, &axis);
  return axis;
}

PlotUnit PlotTorqueUnit(double max_abs_Nm) {
  const double m = std::abs(max_abs_Nm);
  if (!(m >= 1e3)) return {1.0, "N\u00b7m"};  // also NaN: no data
  if (m < 1e6) return {1e-3, "kN\u00b7m"};
  return {1e-6, "MN\u00b7m"};
}

std::string RenderSvgPlot(const std::vector<PlotPanel>& panels, const PlotOptions& options) {
  const double title = options.title.empty() ? 0.0 : kTitleHeight;
  const int columns =
      std::max(1, static_cast<int>(options.panel_width_px / std::max(options.note_column_px, 1.0)));
  const int rows = (static_cast<int>(options.notes.size()) + columns - 1) / columns;
  const double notes = rows == 0 ? 0.0 : kNoteLineHeight * rows + 10.0;
  const double height =
      title + notes + options.panel_height_px * static_cast<double>(panels.size());
  std::string svg = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  svg += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + Px(options.panel_width_px) +
         "\" height=\"" + Px(height) + "\" viewBox=\"0 0 " + Px(options.panel_width_px) + " " +
         Px(height) + "\" font-family=\"sans-serif\">\n";
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>\n";
  if (!options.title.empty()) {
    Text(&svg, 0.5 * options.panel_width_px, 22.0, "middle", 17, options.title);
  }
  if (rows > 0) {
    svg += "<g class=\"notes\">\n";
    for (size_t k = 0; k < options.notes.size(); ++k) {
      const int column = static_cast<int>(k) / rows, row = static_cast<int>(k) % rows;
      Text(&svg, 20.0 + column * options.note_column_px, title + 14.0 + kNoteLineHeight * row,
           "start", 12, options.notes[k]);
    }
    svg += "</g>\n";
  }
  for (size_t p = 0; p < panels.size(); ++p) {
    RenderPanel(panels[p], static_cast<int>(p),
                title + notes + options.panel_height_px * static_cast<double>(p), options, &svg);
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace millkit
