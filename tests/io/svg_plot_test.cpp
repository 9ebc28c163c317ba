// The SVG plot writer: polylines through the drawable points, axes, labels, panels, heat maps.
#include "millkit/io/svg_plot.h"

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

using Catch::Matchers::Contains;
using Catch::Matchers::WithinAbs;
using millkit::PlotAxis;
using millkit::PlotAxisFor;
using millkit::PlotPanel;
using millkit::PlotSeries;
using millkit::PlotTorqueUnit;
using millkit::RenderSvgPlot;

namespace {

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Number of points of the k-th polyline.
int PolylinePoints(const std::string& svg, int k) {
  auto at = svg.find("<polyline");
  for (int i = 0; i < k; ++i) at = svg.find("<polyline", at + 1);
  const auto begin = svg.find("points=\"", at) + 8;
  const auto end = svg.find('"', begin);
  return Count(svg.substr(begin, end - begin), ",");
}

// The k-th polyline element, whole.
std::string Polyline(const std::string& svg, int k) {
  auto at = svg.find("<polyline");
  for (int i = 0; i < k; ++i) at = svg.find("<polyline", at + 1);
  return svg.substr(at, svg.find("/>", at) - at);
}

}  // namespace

TEST_CASE("a line series is drawn through its finite points and breaks at a NaN", "[svg]") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  PlotPanel panel;
  panel.series.push_back({"kd", {1, 2, 3, 4, 5}, {1.0, 2.0, nan, 4.0, 5.0}});
  const std::string svg = RenderSvgPlot({panel});
  REQUIRE(Count(svg, "<polyline") == 2);
  CHECK(PolylinePoints(svg, 0) == 2);
  CHECK(PolylinePoints(svg, 1) == 2);
  CHECK(Count(svg, "<svg") == 1);
  CHECK(Count(svg, "</svg>") == 1);
}

TEST_CASE("markers are one circle per drawable point plus the legend's", "[svg]") {
  PlotPanel panel;
  panel.series.push_back({"cases", {1, 2, 3}, {3, 1, 2}, PlotSeries::Style::kMarkers});
  const std::string svg = RenderSvgPlot({panel});
  CHECK(Count(svg, "<polyline") == 0);
  CHECK(Count(svg, "<circle") == 3 + 1);
}

TEST_CASE("titles and legend labels are XML-escaped", "[svg]") {
  PlotPanel panel;
  panel.title = "Kd <upper> & \"lower\"";
  panel.x_title = "c (N*m/rad)";
  panel.y_title = "Kd";
  panel.series.push_back({"a<b", {0, 1}, {0, 1}});
  const std::string svg = RenderSvgPlot({panel});
  CHECK_THAT(svg, Contains("Kd &lt;upper&gt; &amp; &quot;lower&quot;"));
  CHECK_THAT(svg, Contains(">a&lt;b</text>"));
  CHECK_THAT(svg, Contains(">c (N*m/rad)</text>"));
  CHECK(Count(svg, "<upper>") == 0);
}

TEST_CASE("a log axis has 1-2-5 ticks inside the data and skips non-positive values", "[svg]") {
  PlotPanel panel;
  panel.log_x = true;
  panel.series.push_back({"", {-1.0, 0.0, 3.0, 30.0, 3000.0}, {1, 1, 2, 3, 4}});
  const std::string svg = RenderSvgPlot({panel});
  for (const char* tick :
       {">5</text>", ">10</text>", ">20</text>", ">100</text>", ">2000</text>"}) {
    CHECK_THAT(svg, Contains(tick));
  }
  CHECK(Count(svg, ">1</text>") == 0);  // below the data: no whole-decade padding
  CHECK(Count(svg, ">10000</text>") == 0);
  REQUIRE(Count(svg, "<polyline") == 1);
  CHECK(PolylinePoints(svg, 0) == 3);
}

TEST_CASE("a log axis over 500 to 50 000 is padded to the data, not to whole decades", "[svg]") {
  // The complaint of issue 13 item 8: this range was drawn over 100 … 100 000.
  const PlotAxis axis = PlotAxisFor(500.0, 50000.0, true);
  CHECK(axis.lo < 500.0);
  CHECK(axis.lo >= 400.0);
  CHECK(axis.hi > 50000.0);
  CHECK(axis.hi <= 60000.0);
  CHECK(axis.ticks == std::vector<double>{500, 1000, 2000, 5000, 10000, 20000, 50000});
  CHECK(axis.labels.front() == "500");
  CHECK(axis.labels.back() == "50000");
}

TEST_CASE("a linear axis is padded by a few percent of the span on each side", "[svg]") {
  constexpr double kTight = 1e-12;
  const PlotAxis axis = PlotAxisFor(0.13, 0.87, false);
  CHECK_THAT(axis.lo, WithinAbs(0.13 - millkit::kAxisPadding * 0.74, kTight));
  CHECK_THAT(axis.hi, WithinAbs(0.87 + millkit::kAxisPadding * 0.74, kTight));
  REQUIRE(axis.ticks.size() >= 3);
  for (double tick : axis.ticks) {
    CHECK(tick >= axis.lo);
    CHECK(tick <= axis.hi);
  }
}

TEST_CASE("tick labels carry the digits of the tick step, not 16", "[svg]") {
  // 0.1 + 0.05 k is not exact in binary: printed with %.17g the ticks show 16 digits.
  const PlotAxis fine = PlotAxisFor(0.1, 0.3, false);  // a step of 0.05
  CHECK(fine.labels == std::vector<std::string>{"0.10", "0.15", "0.20", "0.25", "0.30"});
  const PlotAxis large = PlotAxisFor(1.0e7, 2.0e7, false);  // a shared exponent, not 8 digits
  CHECK(large.labels.front() == "1.0e7");
  CHECK(large.labels.back() == "2.0e7");
  const PlotAxis negative = PlotAxisFor(-3.0, 3.0, false);
  CHECK(std::count(negative.labels.begin(), negative.labels.end(), "0") == 1);
  CHECK(std::count(negative.labels.begin(), negative.labels.end(), "-0") == 0);
}

TEST_CASE("linear ticks are round numbers inside the padded data range", "[svg]") {
  PlotPanel panel;
  panel.series.push_back({"", {0.13, 0.87}, {1.04, 1.96}});
  const std::string svg = RenderSvgPlot({panel});
  for (const char* tick :
       {">0.2</text>", ">0.4</text>", ">0.8</text>", ">1.2</text>", ">1.8</text>"}) {
    CHECK_THAT(svg, Contains(tick));
  }
  CHECK(Count(svg, ">0</text>") == 0);  // outside the padded range
  CHECK(Count(svg, ">2</text>") == 0);
}

TEST_CASE("a fitted line is drawn after the trace under it, whatever the series order", "[svg]") {
  PlotPanel panel;
  panel.series.push_back(
      {"fitted", {0, 1, 2}, {0, 1, 0}, PlotSeries::Style::kLine, PlotSeries::Emphasis::kFit});
  panel.series.push_back({"measured",
                          {0, 1, 2},
                          {0, 1.1, 0.1},
                          PlotSeries::Style::kLine,
                          PlotSeries::Emphasis::kTrace});
  const std::string svg = RenderSvgPlot({panel});
  REQUIRE(Count(svg, "<polyline") == 2);
  // Palette colours by series: 0 (fitted) #1f77b4, 1 (measured) #d62728.
  const std::string first = Polyline(svg, 0), second = Polyline(svg, 1);
  CHECK_THAT(first, Contains("#d62728") && Contains("stroke-opacity"));          // the trace, light
  CHECK_THAT(second, Contains("#1f77b4") && Contains("stroke-width=\"2.20\""));  // the fit, thick
  CHECK(svg.find(">fitted</text>") < svg.find(">measured</text>"));  // legend in given order
}

TEST_CASE("normal line series get distinct dash patterns and marker series distinct shapes",
          "[svg]") {
  PlotPanel panel;
  panel.series.push_back({"a", {0, 1}, {0, 1}});
  panel.series.push_back({"b", {0, 1}, {0, 1}});  // on top of a: its gaps show a
  panel.series.push_back({"c", {0, 1}, {1, 0}});
  panel.series.push_back({"p", {0.5}, {0.5}, PlotSeries::Style::kMarkers});
  panel.series.push_back({"q", {0.5}, {0.5}, PlotSeries::Style::kMarkers});
  const std::string svg = RenderSvgPlot({panel});
  CHECK(Count(Polyline(svg, 0), "stroke-dasharray") == 0);  // a: solid
  CHECK_THAT(Polyline(svg, 1), Contains("stroke-dasharray=\"7 4\""));
  CHECK_THAT(Polyline(svg, 2), Contains("stroke-dasharray=\"2 3\""));
  CHECK(Count(svg, "<circle") == 2);                // p: plot and legend
  CHECK(Count(svg, "fill=\"none\"><rect") == 2);    // q: squares, plot and legend
  CHECK(Count(svg, "fill=\"none\"><circle") == 2);  // hollow: what is under them shows
}

TEST_CASE("a heat map draws one cell per value, a colour bar, and a grey cell for no value",
          "[svg]") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  PlotPanel panel;
  panel.heat_map.x = {1.0, 2.0, 3.0};
  panel.heat_map.y = {10.0, 20.0};
  panel.heat_map.z = {1.0, 2.0, 3.0, nan, 5.0, 6.0};
  panel.heat_map.z_title = "Kd";
  const std::string svg = RenderSvgPlot({panel});
  CHECK(Count(svg, "class=\"cell\"") == 6);
  CHECK(Count(svg, "class=\"colour-bar\"") == 1);
  CHECK(Count(svg, "fill=\"#440154\"") == 1);  // the lowest value: the scale's dark end
  CHECK(Count(svg, "fill=\"#fde725\"") == 1);  // the highest: its yellow end
  CHECK(Count(svg, "fill=\"#d9d9d9\"") == 2);  // the NaN cell and its key
  CHECK_THAT(svg, Contains(">no value</text>"));
  CHECK_THAT(svg, Contains(">Kd</text>"));
  CHECK_THAT(svg, Contains(">2.00</text>"));  // a cell's value, three digits
  CHECK_THAT(svg, Contains(">20</text>"));    // an axis tick at a cell centre
}

TEST_CASE("a heat map with a fixed colour range colours by that range", "[svg]") {
  PlotPanel panel;
  panel.heat_map.x = {1.0, 2.0};
  panel.heat_map.y = {1.0};
  panel.heat_map.z = {1.0, 2.0};
  panel.heat_map.z_lo = 0.0;
  panel.heat_map.z_hi = 4.0;
  const std::string svg = RenderSvgPlot({panel});
  CHECK(Count(svg, "class=\"cell\" x=\"84.00\"") == 1);
  CHECK(Count(svg, "fill=\"#440154\"") == 0);  // neither cell at the scale's ends
  CHECK(Count(svg, "fill=\"#fde725\"") == 0);
  CHECK(Count(svg, "fill=\"#21918c\"") == 1);  // 2 of [0, 4]: the middle colour
}

TEST_CASE("a heat map whose size or centres do not fit is refused", "[svg]") {
  PlotPanel panel;
  panel.heat_map.x = {1.0, 2.0};
  panel.heat_map.y = {1.0, 2.0};
  panel.heat_map.z = {1.0, 2.0, 3.0};
  CHECK_THROWS_AS(RenderSvgPlot({panel}), std::invalid_argument);
  panel.heat_map.z.push_back(4.0);
  panel.heat_map.x = {2.0, 1.0};
  CHECK_THROWS_AS(RenderSvgPlot({panel}), std::invalid_argument);
}

TEST_CASE("notes are listed under the title and make room above the panels", "[svg]") {
  millkit::PlotOptions options;
  options.title = "fit";
  options.panel_height_px = 300;
  options.notes = {"stiffness = 1.0 \u00b1 0.1", "damping = 2.0 \u00b1 0.2", "gap = 3"};
  const std::string svg = RenderSvgPlot({PlotPanel{}}, options);
  CHECK_THAT(svg, Contains(">damping = 2.0 \u00b1 0.2</text>"));
  // 720 px holds two 360 px columns: two rows of 16 px and 10 px below them.
  CHECK_THAT(svg, Contains("height=\"372.00\""));  // 30 + 2 × 16 + 10 + 300
}

TEST_CASE("a torque axis is in newton, kilonewton or meganewton metres by the largest torque",
          "[svg]") {
  CHECK(PlotTorqueUnit(800.0).unit == "N\u00b7m");
  CHECK(PlotTorqueUnit(800.0).factor == 1.0);
  CHECK(PlotTorqueUnit(-2.5e5).unit == "kN\u00b7m");
  CHECK(PlotTorqueUnit(-2.5e5).factor == 1e-3);
  CHECK(PlotTorqueUnit(3.0e6).unit == "MN\u00b7m");
  CHECK(PlotTorqueUnit(3.0e6).factor == 1e-6);
}

TEST_CASE("panels stack vertically, each with its own axes", "[svg]") {
  millkit::PlotOptions options;
  options.title = "two panels";
  options.panel_height_px = 300;
  PlotPanel a, b;
  a.series.push_back({"", {0, 1}, {0, 1}});
  const std::string svg = RenderSvgPlot({a, b}, options);
  CHECK(Count(svg, "class=\"panel\"") == 2);
  CHECK_THAT(svg, Contains("height=\"630.00\""));  // 30 px title + 2 × 300
  CHECK_THAT(svg, Contains("no data"));            // panel b
}

TEST_CASE("a series whose x and y differ in length is refused", "[svg]") {
  PlotPanel panel;
  panel.series.push_back({"bad", {0, 1, 2}, {0, 1}});
  CHECK_THROWS_AS(RenderSvgPlot({panel}), std::invalid_argument);
}

TEST_CASE("error bars are drawn about their markers and widen the y axis to hold them", "[svg]") {
  PlotPanel panel;
  PlotSeries points{"values", {0, 1, 2}, {1, 2, 1.5}, PlotSeries::Style::kMarkers};
  points.y_error = {0.5, 0.0, std::numeric_limits<double>::quiet_NaN()};  // one bar only
  panel.series.push_back(points);
  const std::string svg = RenderSvgPlot({panel});
  REQUIRE(Count(svg, "class=\"error-bars\"") == 1);
  const auto at = svg.find("class=\"error-bars\"");
  const std::string path = svg.substr(at, svg.find("/>", at) - at);
  CHECK(Count(path, "M") == 3);  // the bar and its two caps
  // The data span 1 … 2; the bar reaches 0.5: ticks at a step of 0.5 from 0.5 (without the bar:
  // a step of 0.2 from 1.0).
  CHECK_THAT(svg, Contains(">0.5</text>"));
  CHECK_THAT(svg, Contains(">1.5</text>"));
  CHECK(Count(svg, ">1.2</text>") == 0);
}

TEST_CASE("a series with error bars for some points only is refused", "[svg]") {
  PlotPanel panel;
  PlotSeries points{"bad", {0, 1, 2}, {0, 1, 2}, PlotSeries::Style::kMarkers};
  points.y_error = {0.1, 0.1};
  panel.series.push_back(points);
  CHECK_THROWS_AS(RenderSvgPlot({panel}), std::invalid_argument);
}
