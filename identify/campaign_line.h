// The synthetic campaign line of the campaign tests and bench_campaign (issue 15; test and bench
// support, not part of millkit_identify): a two-mass line whose spindle rattles in its gap, motor
// 2000, roll 800 kg·m², spindle 5e6 N·m/rad (one mode at 14.9 Hz), damping 5000 N·m·s/rad
// (ζ ≈ 5 %), gap 10 mrad in the prior; the roll load −150 kN·m twists the spindle by about twice
// the gap. The truth: a gap that opens by kCampaignWearPerDay_rad a day from
// kCampaignGapAtDay0_rad, damping kCampaignTrueDamping and bite time kCampaignTrueBite_s.
#pragma once

#include <string>

#include "millkit/driveline/scene.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/identify/record_generator.h"

namespace millkit::identify {

inline constexpr const char* kCampaignLineScene = R"([scene]
name = "two-mass campaign line"
duration = 0.3
sample_rate = 4000

[initial]
speed = 10.0

[[mass]]
name = "motor"
inertia = 2000.0
[[mass]]
name = "roll"
inertia = 800.0

[[link]]
name = "spindle"
between = ["motor", "roll"]
stiffness = 5.0e6
damping = 5000.0
backlash = 0.010

[[torque]]
at = "roll"
after = -150000.0
start = 0.05
rise = 0.008
)";

inline constexpr double kCampaignGapAtDay0_rad = 0.008;
inline constexpr double kCampaignWearPerDay_rad = 1.0e-4;
inline constexpr double kCampaignTrueDamping = 5200.0;
inline constexpr double kCampaignTrueBite_s = 0.052;

// A record (CSV text) of the line (`prior`, loaded from kCampaignLineScene) with gap `gap_rad`
// and the true damping and bite time: 2 kHz, 1 % noise, 12-bit ADC, gain 1.02, offset 500 N·m.
inline std::string CampaignLineRecordCsv(const driveline::Scene& prior, double gap_rad,
                                         unsigned long seed) {
  driveline::Scene truth = prior;
  driveline::ParseSceneParameter(truth, "spindle.backlash", "campaign line").Set(gap_rad, &truth);
  driveline::ParseSceneParameter(truth, "spindle.damping", "campaign line")
      .Set(kCampaignTrueDamping, &truth);
  driveline::ParseSceneParameter(truth, "bite_time", "campaign line")
      .Set(kCampaignTrueBite_s, &truth);
  RecordSpec spec;
  spec.defects.sample_rate_Hz = 2000.0;
  spec.defects.noise_fraction = 0.01;
  spec.defects.bits = 12;
  spec.defects.seed = seed;
  spec.channels = {{"spindle", truth.LinkIndex("spindle"), 1.02, 500.0}};
  return FormatOscillogram(GenerateRecord(truth, spec));
}

}  // namespace millkit::identify
