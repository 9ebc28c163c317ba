// What to fit (SPEC.md §4, issues 3 and 12; the user's reference is docs/identify.md): free scene
// parameters with bounds and starts, the channel → link mapping with per-channel weights and
// nuisance gain/offset, the time window and the multi-start settings. Read from a TOML file
// (`millkit identify --config fit.toml`):
//
//   [fit]
//   window = [0.0, 0.4]    # s, part of the record fitted (default: the whole record)
//   scan = 128             # coarse scan points over the scanned parameters (default 128; 0 = none)
//   starts = 4             # distinct starts refined by Ceres (default 4, >= 1)
//   seed = 1               # of the scan's Latin hypercube
//   time_origin = 7.25     # s, record time of the model's t = 0 (default: each record's first
//                          # sample); bite_time counts from it, the window is in record time
//   [set]                  # known values replacing the scene's, not fitted
//   "lower_spindle.gap_position" = 1.0
//   [[free]]               # one per fitted scene parameter (names: scene_parameter.h)
//   name = "upper_spindle.backlash"
//   start = 0.015          # default: the scene's value (after [set])
//   lower = 0.002
//   upper = 0.04
//   scan = true            # part of the coarse scan (default: true)
//   per_record = false     # with several records (--data more than once): one value per
//                          # record (default: true for bite_time, false otherwise)
//   [[channel]]
//   column = "upper_torque"  # record column (or iba signal ID, "[3:12]")
//   link = "upper_spindle"   # default: the column name
//   unit = "kN*m"            # N*m, kN*m or MN*m (default: the record's units row, else N*m)
//   weight = 1.0e-3          # 1/unit (default: 1/noise, measured on the record before the bite)
//   gain = true              # fit a gain (default true; start 1)
//   offset = true            # fit an offset (default true; start: mean before bite)
//   lowpass = 800.0          # Hz: the recorder's first-order anti-alias filter, applied to the
//                            # model (default 0: none; see identify/instrument_filter.h)
//   gain_bounds = [0.5, 2.0] # the gain's bounds (default [0.5, 2])
//   offset_limit = 5.0e4     # unit: the offset's bound ± (default: the channel's peak |value|)
//
// Without a config: every record column named like a link is a channel; free are the damping of
// every elastic link in [d/10, 10 d], the backlash of every link with b > 0 in [b/5, 3 b], and
// bite_time within ±0.02 s; window = the whole record.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/identify/oscillogram.h"

namespace millkit::identify {

// The scan's defaults, set by the random-lines benchmark (bench/identify/bench_random_lines.cpp).
inline constexpr int kDefaultScanPoints = 128;
inline constexpr int kDefaultStarts = 4;

struct FreeParameter {
  driveline::SceneParameter parameter;
  double start = 0.0;
  double lower = 0.0;
  double upper = 0.0;
  bool scan = false;
  bool per_record = false;  // one value per record when several are fitted together
};

// A torque unit a channel may be logged in: its canonical name ("N*m", "kN*m" or "MN*m") and
// N·m per unit. Accepts the spellings loggers use: N*m, Nm, N.m, N m, N·m, with k or M, in
// brackets or not. None for anything else.
struct TorqueUnit {
  std::string name;
  double newton_metres = 1.0;
};
std::optional<TorqueUnit> ParseTorqueUnit(const std::string& text);

struct ChannelSpec {
  std::string column;  // record column: its name, or an iba signal ID
  std::string link;
  int link_index = -1;  // scene link
  // The column's unit (config `unit`, else the record's units row, else N*m). The fit works in
  // N·m and reports the channel (offset, noise, residual, traces) in this unit.
  TorqueUnit unit{"N*m", 1.0};
  std::optional<double> weight;  // 1/N·m; none: 1/noise measured on the record (record_noise.h)
  bool fit_gain = true;
  bool fit_offset = true;
  double lowpass_Hz = 0.0;  // the recorder's first-order anti-alias filter, modelled (0: none)
  double gain_lower = 0.5;
  double gain_upper = 2.0;
  std::optional<double> offset_limit_Nm;  // none: the channel's peak |value| in the window
};

// How the fit differentiates the simulation while iterating (FitOptions::derivatives):
// "sensitivity", "forward", "central"; ParseDerivatives returns false for anything else.
enum class Derivatives { kSensitivity, kForward, kCentral };
const char* DerivativesName(Derivatives derivatives);
bool ParseDerivatives(const std::string& text, Derivatives* derivatives);

struct FitConfig {
  std::vector<FreeParameter> free;
  std::vector<ChannelSpec> channels;
  double window_start_s = 0.0;
  double window_end_s = 0.0;
  int scan_points = kDefaultScanPoints;
  int starts = kDefaultStarts;
  unsigned seed = 1;
  // [fit] derivatives: overrides FitOptions::derivatives when given.
  std::optional<Derivatives> derivatives;
  // [fit] time_origin: the record time (s) that is the model's time zero in every record; none:
  // each record's first sample.
  std::optional<double> time_origin_s;
  // [set]: known values replacing the scene's, not fitted (ApplySetValues puts them in a scene).
  std::vector<std::pair<driveline::SceneParameter, double>> set;
};

// Reads the config and checks everything against the scene (with the config's [set] values
// applied to a copy: the caller applies them to the scene it fits, ApplySetValues) and every
// record. Throws InputError naming file and key: unknown keys or parameter names, lower
// > upper, a start outside its bounds, bounds outside the parameter's physical range, a window
// outside a record or with fewer than kMinRecordSamples samples, a channel column missing from a
// record, an unknown link, a repeated parameter or channel. The default window is the time span
// every record covers.
FitConfig LoadFitConfig(const std::string& path, const std::vector<Oscillogram>& records,
                        const driveline::Scene& scene);
FitConfig LoadFitConfig(const std::string& path, const Oscillogram& record,
                        const driveline::Scene& scene);

// Sets the config's [set] values in `scene` and validates it.
void ApplySetValues(const FitConfig& config, driveline::Scene* scene);

// The defaults above: channels are the columns of the first record named like links. Throws
// InputError when there is none.
FitConfig DefaultFitConfig(const driveline::Scene& scene, const std::vector<Oscillogram>& records);
FitConfig DefaultFitConfig(const driveline::Scene& scene, const Oscillogram& record);

// Checks the rules above on a config built in code; `where` prefixes messages.
void ValidateFitConfig(const FitConfig& config, const std::vector<Oscillogram>& records,
                       const std::string& where);

}  // namespace millkit::identify
