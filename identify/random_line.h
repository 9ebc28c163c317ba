// Seeded random drive lines for benchmarking identification (issue 12): one seed gives a true
// line, the record it makes, the engineer's prior of it and the default fit config a new user would
// run. Test and bench support, not part of millkit_identify.
//
// Drawn from one std::mt19937_64(seed) through its raw 64-bit output (no std::*_distribution, whose
// sequences differ between standard libraries), so a seed names the same case on every platform:
//  - 2–6 masses, inertias log-uniform in [300, 40 000] kg·m²; topology a chain, a mill stand (a
//    chain ending at a pinion stand that splits into two rolls) or a random tree (each mass
//    joined to a random earlier one). Mass 0 is the motor; every other leaf is a roll.
//  - Stiffnesses such that every non-zero natural frequency of the line without gaps lies in
//    [kMinModeHz, kMaxModeHz]: per-link two-mass frequencies drawn, then one common scale drawn
//    from the range that fits, redrawn when the spread of the modes is too wide (bounded; a
//    two-mass line, which always fits, is the last resort).
//  - Damping ratios ζ in [2, 15] %: d = 2 ζ sqrt(c J_eff), J_eff = J_a J_b / (J_a + J_b).
//  - Backlash (total) on each link with probability 1/2, log-uniform in [0.5, 40] mrad;
//    gap_position is the scene default (−1: the gap is open on the side the load closes).
//  - A ramp 0 → −L over 2–15 ms on every roll, L log-uniform in [50, 300] kN·m, then all loads
//    scaled together so that the largest static link twist is 1–10 times the largest gap (the
//    torque level itself does not matter to the fit: the noise is relative). Bite at 0.05 s in
//    the prior, shifted uniformly by ±10 ms in the truth. No drive: the line coasts from 10 rad/s.
//  - A record of 0.3 s, 1–3 channels (torques of distinct links, spindles of the rolls first),
//    log-uniform 1–10 kHz, noise 0.5–2 % of the peak, gain 1 ± 3 %, offset ± 2 % of the peak,
//    12-bit ADC, no recorder filter.
//  - The prior: every damping × a log-uniform factor in [1/1.6, 1.6], every gap × [1/1.4, 1.4],
//    the nominal bite time.
//
// Variants check the fit on lines this draw never makes. Each takes the base case of the seed
// and changes it with draws from a second generator (seeded from the seed), so the base case,
// and every result measured on it, stays as it was:
//  - kDrive: a speed-PI drive on the motor, bandwidth ω log-uniform in 5–20 Hz (kp = J_motor ω,
//    ki = kp ω / 4, lag 0.1 / ω, no torque limit reached), truth and prior alike; the record
//    made again with the same spec. The load is taken up over tenths of a second.
//  - kWidePrior: the prior's dampings off by up to ×3 and its gaps by up to ×2.
//  - kStiffness: one link's stiffness fitted too (the prior's × [1/1.3, 1.3], bounds ÷2 to ×2).
//  - kNoPull: the no_pull contact law (a contact that would pull opens), truth and prior alike;
//    the record made again with the same spec.
//  - kLinear: the linear contact law (in contact m = τc + τd, which may pull; the torque jumps
//    by τd where a contact starts and ends), truth and prior alike; the record made again.
//  - kStepLoad: every load a step at the bite (rise 0) instead of a 2–15 ms ramp, truth and prior
//    alike: the right-hand side jumps at the fitted bite time; the record made again.
//  - kLowpass: the recorder's first-order anti-alias filter, cutoff log-uniform in 0.1–0.4 of
//    the record's rate, in the record (made again) and in every channel of the fit's config.
//  - kFastLowpass: the same with the cutoff log-uniform in 0.5–5 of the rate (a recorder filter
//    above half its rate; the record filtered on a grid 64 times finer).
// Variants combine ("no-pull+lowpass"): each in turn, the k-th with a stream of its own (the
// first with the stream it takes alone).
#pragma once

#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/identify/record_generator.h"

namespace millkit::identify {

inline constexpr double kMinModeHz = 15.0;
inline constexpr double kMaxModeHz = 120.0;

enum class RandomLineVariant {
  kBase,
  kDrive,
  kWidePrior,
  kStiffness,
  kNoPull,
  kLinear,
  kStepLoad,
  kLowpass,
  kFastLowpass
};

struct RandomLineCase {
  unsigned long seed = 0;
  // One line: masses, topology, modes, gaps, loads, channels, rate and noise.
  std::string description;
  driveline::Scene truth;  // the line the record was made from
  driveline::Scene prior;  // the scene handed to the fit (dampings, gaps, bite time off)
  Oscillogram record;
  FitConfig config;                  // DefaultFitConfig(prior, record): what a new user gets
  std::vector<double> truth_values;  // true value of each config.free parameter, same order
  RecordSpec record_spec;            // what the record was made with
};

// Always returns a case: a draw whose record cannot be simulated is redrawn from the same
// generator. Throws std::runtime_error only if 20 draws in a row fail (never seen in 500 seeds).
RandomLineCase MakeRandomLineCase(unsigned long seed);
// The seed's base case, changed as the variant says (or as each of the variants says, in turn);
// a variant that makes the record again (all but wide-prior and stiffness) throws
// SolverFailure when it cannot be simulated (never seen in 400 seeds of each).
RandomLineCase MakeRandomLineCase(unsigned long seed, RandomLineVariant variant);
RandomLineCase MakeRandomLineCase(unsigned long seed,
                                  const std::vector<RandomLineVariant>& variants);
// "base", "drive", "wide-prior", "stiffness", "no-pull", "linear", "step-load", "lowpass",
// "fast-lowpass"; false for any other name.
bool ParseRandomLineVariant(const std::string& name, RandomLineVariant* variant);
// Names joined by '+' ("linear+lowpass"); false if any is not a variant.
bool ParseRandomLineVariants(const std::string& names, std::vector<RandomLineVariant>* variants);

// Elastic natural frequencies (Hz, ascending) of the undamped line with every gap closed
// (millkit/driveline/natural_frequencies.h without the rigid-body mode).
std::vector<double> ElasticModesHz(const driveline::Scene& scene);

}  // namespace millkit::identify
