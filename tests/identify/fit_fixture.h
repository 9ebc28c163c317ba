// Test support for identification: the bundled five-mass scene, its fit config and synthetic
// records made in code from stated true values (the same values as
// datasets/records/mill5_two_spindles.spec.toml).
#pragma once

#include <catch2/catch.hpp>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/record_generator.h"
#include "support/run_cli.h"

namespace millkit::identify::testing {

inline const std::map<std::string, double>& Mill5Truth() {
  static const std::map<std::string, double> truth = {{"motor_shaft.damping", 32000.0},
                                                      {"main_coupling.damping", 75000.0},
                                                      {"upper_spindle.damping", 6200.0},
                                                      {"lower_spindle.damping", 3300.0},
                                                      {"main_coupling.backlash", 0.0052},
                                                      {"upper_spindle.backlash", 0.0235},
                                                      {"lower_spindle.backlash", 0.0265},
                                                      {"upper_spindle.stiffness", 1.15e7},
                                                      {"bite_time", 0.0537}};
  return truth;
}
inline constexpr double kUpperGain = 1.03;
inline constexpr double kUpperOffset = 1200.0;
inline constexpr double kLowerGain = 0.97;
inline constexpr double kLowerOffset = -800.0;

inline driveline::Scene Mill5Scene() {
  return driveline::LoadScene(millkit::testing::SourcePath("datasets/scenes/mill5_bite.toml"));
}

// The scene with the true values (and `extra` values) applied.
inline driveline::Scene Mill5TruthScene(const std::map<std::string, double>& extra = {}) {
  driveline::Scene scene = Mill5Scene();
  for (const auto* values : {&Mill5Truth(), &extra}) {
    for (const auto& [name, value] : *values) {
      driveline::ParseSceneParameter(scene, name, "test").Set(value, &scene);
    }
  }
  return scene;
}

// A two-channel record (upper and lower spindle torque) over 0.4 s, at 2 kHz unless given.
inline Oscillogram Mill5Record(double noise_fraction, int bits, double lowpass_Hz,
                               unsigned long seed, const std::map<std::string, double>& extra = {},
                               double sample_rate_Hz = 2000.0) {
  RecordSpec spec;
  spec.defects.sample_rate_Hz = sample_rate_Hz;
  spec.defects.duration_s = 0.4;
  spec.defects.noise_fraction = noise_fraction;
  spec.defects.bits = bits;
  spec.defects.lowpass_Hz = lowpass_Hz;
  spec.defects.seed = seed;
  const driveline::Scene truth = Mill5TruthScene(extra);
  spec.channels = {{"upper_spindle", truth.LinkIndex("upper_spindle"), kUpperGain, kUpperOffset},
                   {"lower_spindle", truth.LinkIndex("lower_spindle"), kLowerGain, kLowerOffset}};
  return GenerateRecord(truth, spec);
}

// The tests fit 0–0.3 s of the 0.4 s records unless they ask for the whole record (a window
// end of 0). The bundled config fits the whole record; these tests check what does not depend on
// the window's length, and the shorter one keeps the sanitizer stage's fits inside CI's budget.
inline constexpr double kTestWindowEnd_s = 0.3;

// The bundled fit config (8 link parameters + bite time; gain and offset per channel), with the
// recorder filter as given, the window up to window_end_s, no scan and one start unless changed
// by the caller.
inline FitConfig Mill5Config(const std::vector<Oscillogram>& records, driveline::Scene* scene,
                             double lowpass_Hz = 0.0, double window_end_s = kTestWindowEnd_s) {
  FitConfig config =
      LoadFitConfig(millkit::testing::SourcePath("datasets/records/mill5_two_spindles.fit.toml"),
                    records, *scene);
  ApplySetValues(config, scene);
  for (auto& channel : config.channels) channel.lowpass_Hz = lowpass_Hz;
  if (window_end_s > 0.0) config.window_end_s = window_end_s;
  config.scan_points = 0;
  config.starts = 1;
  return config;
}
inline FitConfig Mill5Config(const Oscillogram& record, driveline::Scene* scene,
                             double lowpass_Hz = 0.0, double window_end_s = kTestWindowEnd_s) {
  return Mill5Config(std::vector<Oscillogram>{record}, scene, lowpass_Hz, window_end_s);
}

// Two fits that must agree: both succeed with the same verdict, and every parameter value agrees
// within `relative` (0: bit for bit).
inline void CheckSameFit(const FitResult& a, const FitResult& b, double relative = 0.0) {
  REQUIRE(a.summary.success);
  REQUIRE(b.summary.success);
  CHECK(b.summary.verdict == a.summary.verdict);
  REQUIRE(b.parameters.size() == a.parameters.size());
  for (size_t i = 0; i < a.parameters.size(); ++i) {
    INFO(a.parameters[i].name << ": " << a.parameters[i].value << " vs " << b.parameters[i].value);
    CHECK(std::abs(b.parameters[i].value - a.parameters[i].value) <=
          relative * std::abs(a.parameters[i].value));
  }
}

}  // namespace millkit::identify::testing
