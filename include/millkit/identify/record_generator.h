// Synthetic oscillograms with the defects of real strain-gauge records (issue 3, datasets/records):
// the exact solution of a scene with stated true parameters, sampled through a first-order
// anti-alias low-pass, with per-channel gain error and offset, Gaussian noise as a fraction of the
// channel's peak torque, and quantisation by an ADC of `bits` bits over ±full_scale. The bite time
// is whatever the truth scene says (set `bite_time` in [truth] to move it).
//
// Spec file (TOML), also the truth file kept beside the record:
//   [record]
//   sample_rate = 2000      # Hz, record grid k / sample_rate from t = 0
//   duration = 0.4          # s (default: the scene's)
//   noise = 0.01            # σ / peak |torque| of each channel (0 = none)
//   bits = 12               # ADC resolution (0 = no quantisation)
//   full_scale = 1.5        # ADC range ±full_scale · peak |gain·torque + offset|
//   lowpass = 800           # Hz, first-order anti-alias filter (0 = none)
//   oversample = 16         # simulation samples per record sample (filter grid)
//   seed = 1
//   [truth]                 # true values of scene parameters (names: scene_parameter.h)
//   "upper_spindle.damping" = 5200.0
//   bite_time = 0.0512
//   [[channel]]
//   column = "upper_spindle"   # record column
//   link = "upper_spindle"     # default: the column name
//   gain = 1.02                # true gain error (default 1)
//   offset = 800.0             # N·m (default 0)
#pragma once

#include <functional>
#include <random>
#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/identify/oscillogram.h"

namespace millkit::identify {

struct RecordChannel {
  std::string column;
  int link_index = -1;
  double gain = 1.0;
  double offset_Nm = 0.0;
};

struct RecordDefects {
  double sample_rate_Hz = 2000.0;
  double duration_s = 0.0;  // 0: the scene's duration
  double noise_fraction = 0.0;
  int bits = 0;
  double full_scale = 1.5;
  double lowpass_Hz = 0.0;
  int oversample = 16;
  unsigned long seed = 1;
};

struct RecordSpec {
  std::vector<RecordChannel> channels;
  RecordDefects defects;
};

// Reads a spec, applies its [truth] values to `scene` (validated). Throws InputError naming the
// file and key.
RecordSpec LoadRecordSpec(const std::string& path, driveline::Scene* scene);

// Simulates `truth` and makes the record. Throws SolverFailure when the simulation fails.
// `progress`, when given, is called during the simulation with the fraction done
// (SimulationOptions::progress).
Oscillogram GenerateRecord(const driveline::Scene& truth, const RecordSpec& spec,
                           const std::function<void(double fraction)>& progress = {});

// Standard normal deviates from a seeded mt19937_64 (Box–Muller): the same sequence on every
// platform, unlike std::normal_distribution.
class GaussianNoise {
 public:
  explicit GaussianNoise(unsigned long seed) : random_(seed) {}
  double Next();

 private:
  std::mt19937_64 random_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace millkit::identify
