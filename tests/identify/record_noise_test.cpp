// A record's own noise (identify/record_noise.h): the quiet stretch ends before the response,
// however slowly the response rises, and noise that is not white does not cut it short.
#include "identify/record_noise.h"

#include <catch2/catch.hpp>
#include <cmath>

#include "millkit/identify/record_generator.h"

namespace millkit::identify {
namespace {

constexpr double kRate_Hz = 4000.0;
constexpr double kBite_s = 0.05;
constexpr double kSigma = 1.0;

// 0.3 s of white noise σ = kSigma, plus `hum` (a 50 Hz sine of that amplitude) and a response
// from kBite_s that rises linearly to `level` over `rise_s`, then holds.
Oscillogram Record(double level, double rise_s, double hum, unsigned long seed) {
  Oscillogram record;
  record.source = "record.csv";
  record.channels = {"spindle"};
  record.values.resize(1);
  GaussianNoise noise(seed);
  for (int k = 0; k < static_cast<int>(0.3 * kRate_Hz); ++k) {
    const double t = k / kRate_Hz;
    const double response = level * std::clamp((t - kBite_s) / rise_s, 0.0, 1.0);
    record.time_s.push_back(t);
    record.values[0].push_back(response + hum * std::sin(2.0 * M_PI * 50.0 * t) +
                               kSigma * noise.Next());
  }
  return record;
}

double EndTime(const Oscillogram& record) { return record.time_s[QuietStretchEnd(record, {0})]; }

TEST_CASE("The quiet stretch ends before a slowly rising response starts") {
  // 400 σ over 0.25 s: its first tenth comes 25 ms after the bite, when it is already 40 σ.
  for (unsigned long seed = 1; seed <= 5; ++seed) {
    const Oscillogram record = Record(400.0 * kSigma, 0.25, 0.0, seed);
    const int end = QuietStretchEnd(record, {0});
    CHECK(record.time_s[end] <= kBite_s);
    const ChannelNoise noise = EstimateChannelNoise(record, 0, end, 0, 1200);
    CHECK(noise.from_quiet_stretch);
    CHECK(noise.sigma_Nm == Approx(kSigma).epsilon(0.15));
    // The stretch is white noise: no lag is correlated beyond 4 / √m.
    for (const double rho : noise.autocorrelation) CHECK(std::abs(rho) < 4.0 / std::sqrt(end));
  }
}

TEST_CASE("A fast response keeps the quiet stretch up to the margin before it") {
  const Oscillogram record = Record(400.0 * kSigma, 0.002, 0.0, 7);
  const double end = EndTime(record);
  CHECK(end <= kBite_s);
  CHECK(end >= (1.0 - kQuietMargin) * kBite_s - 2.0 / kRate_Hz);
}

TEST_CASE("Hum before the bite is noise, not the response") {
  // A 50 Hz hum of 3 σ: the line through the first half does not follow it, and its peaks stay
  // below kOnsetSigmas times the RMS about that line.
  const Oscillogram record = Record(400.0 * kSigma, 0.25, 3.0 * kSigma, 3);
  const double end = EndTime(record);
  CHECK(end <= kBite_s);
  CHECK(end >= 0.7 * kBite_s);
}

}  // namespace
}  // namespace millkit::identify
