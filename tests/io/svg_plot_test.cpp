// The SVG plot writer: polylines through the drawable points, axes, labels, panels.
#include "io/svg_plot.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <string>

using Catch::Matchers::Contains;
using millkit::PlotPanel;
using millkit::PlotSeries;
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

TEST_CASE("a log axis has decade ticks covering the data and skips non-positive values", "[svg]") {
  PlotPanel panel;
  panel.log_x = true;
  panel.series.push_back({"", {-1.0, 0.0, 3.0, 30.0, 3000.0}, {1, 1, 2, 3, 4}});
  const std::string svg = RenderSvgPlot({panel});
  for (const char* tick :
       {">1</text>", ">10</text>", ">100</text>", ">1000</text>", ">10000</text>"}) {
    CHECK_THAT(svg, Contains(tick));
  }
  REQUIRE(Count(svg, "<polyline") == 1);
  CHECK(PolylinePoints(svg, 0) == 3);
}

TEST_CASE("linear ticks are round numbers that enclose the data", "[svg]") {
  PlotPanel panel;
  panel.series.push_back({"", {0.13, 0.87}, {1.04, 1.96}});
  const std::string svg = RenderSvgPlot({panel});
  for (const char* tick :
       {">0</text>", ">0.2</text>", ">0.6</text>", ">1</text>", ">1.8</text>", ">2</text>"}) {
    CHECK_THAT(svg, Contains(tick));
  }
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
