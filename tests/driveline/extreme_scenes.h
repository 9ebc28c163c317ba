// Test support (issue 11): a seeded generator of valid but extreme small drive-line scenes, for the
// hard-case test, the libFuzzer harness and bench/driveline. Ranges: 1–4 masses (0.001–1e4 kg·m²)
// in a random tree; stiffness 1…1e12 N·m/rad; damping 0 or 1e-3…1e10 N·m·s/rad; gaps 0 or
// 1e-12…0.3 rad at any gap_position; gear ratios 0.01…100; every contact law; loads ±1…1e5 N·m
// with rise 0 or 1e-10…1e-2 s; an optional PI drive with lag 1e-7…1 s. The sample rate resolves
// the fastest mode (the scene rule), and the run has at most about 2000 samples.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include "millkit/driveline/model.h"
#include "millkit/driveline/scene.h"

namespace millkit::driveline::testing {

inline constexpr int kExtremeMaxSamples = 2000;

class ExtremeSceneGenerator {
 public:
  explicit ExtremeSceneGenerator(std::uint64_t seed) : random_(seed) {}

  Scene Next() {
    Scene scene;
    scene.name = "extreme";
    const int masses = Integer(1, 4);
    for (int i = 0; i < masses; ++i) {
      scene.masses.push_back({"m" + std::to_string(i), LogUniform(1e-3, 1e4)});
    }
    const ContactLaw laws[] = {ContactLaw::kLimited, ContactLaw::kNoPull, ContactLaw::kLinear};
    scene.contact = laws[Integer(0, 2)];
    for (int i = 1; i < masses; ++i) {
      Link link;
      link.name = "l" + std::to_string(i);
      const int parent = Integer(0, i - 1);
      const bool forward = Chance(0.7);
      link.from = forward ? parent : i;
      link.to = forward ? i : parent;
      link.stiffness_Nm_per_rad = LogUniform(1.0, 1e12);
      link.damping_Nms_per_rad = Chance(0.2) ? 0.0 : LogUniform(1e-3, 1e10);
      link.backlash_rad = Chance(0.4) ? 0.0 : LogUniform(1e-12, 0.3);
      const double positions[] = {-1.0, 0.0, 1.0, Uniform(-1.0, 1.0)};
      link.gap_position = positions[Integer(0, 3)];
      link.ratio = Chance(0.6) ? 1.0 : LogUniform(0.01, 100.0);
      scene.links.push_back(link);
    }
    scene.initial_speed_rad_per_s = Chance(0.5) ? 0.0 : Uniform(-10.0, 10.0);
    double duration = LogUniform(0.01, 10.0);
    const int sources = Integer(0, 2);
    for (int s = 0; s < sources; ++s) {
      TorqueSource source;
      source.name = "[[torque]] #" + std::to_string(s + 1);
      source.mass = Integer(0, masses - 1);
      const double start = Uniform(0.0, 0.8) * duration;
      const double rise = Chance(0.2) ? 0.0 : LogUniform(1e-10, 1e-2);
      source.times_s = {start, start + rise};
      source.values_Nm = {Signed(1.0, 1e5) * (Chance(0.5) ? 1.0 : 0.0), Signed(1.0, 1e5)};
      scene.torques.push_back(source);
    }
    if (Chance(0.4)) {
      Drive drive;
      drive.mass = Integer(0, masses - 1);
      drive.speed_ref_rad_per_s = Uniform(-100.0, 100.0);
      drive.kp = Chance(0.1) ? 0.0 : LogUniform(1e-3, 1e6);
      drive.ki = Chance(0.3) ? 0.0 : LogUniform(1e-3, 1e7);
      if (drive.kp == 0.0 && drive.ki == 0.0) drive.kp = 1.0;
      drive.lag_s = LogUniform(1e-7, 1.0);
      drive.limit_Nm = LogUniform(1.0, 1e6);
      scene.drive = drive;
    }
    // The scene rule: sample_rate >= 4 × the fastest mode (after band reduction); a few samples
    // per period more, and a duration that keeps the run at most kExtremeMaxSamples samples.
    double rate = LogUniform(10.0, 1e4);
    const Scene reduced = ReducedScene(scene);
    const double fastest = HighestModeHz(reduced, ReduceToBand(reduced));
    if (std::isfinite(fastest)) rate = std::max(rate, 1.25 * kSamplesPerFastestPeriod * fastest);
    scene.sample_rate_Hz = rate;
    duration = std::min(duration, (kExtremeMaxSamples - 0.5) / rate);
    // Sources start within the run.
    for (auto& source : scene.torques) {
      const double rise = source.times_s[1] - source.times_s[0];
      source.times_s[0] = std::min(source.times_s[0], 0.8 * duration);
      source.times_s[1] = source.times_s[0] + rise;
    }
    scene.duration_s = duration;
    return scene;
  }

 private:
  double Uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(random_);
  }
  double LogUniform(double lo, double hi) { return std::exp(Uniform(std::log(lo), std::log(hi))); }
  double Signed(double lo, double hi) { return (Chance(0.5) ? 1.0 : -1.0) * LogUniform(lo, hi); }
  int Integer(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(random_); }
  bool Chance(double p) { return Uniform(0.0, 1.0) < p; }

  std::mt19937_64 random_;
};

}  // namespace millkit::driveline::testing
