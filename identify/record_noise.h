// What a record itself says about its noise, before any model is fitted (identify/ internal).
//
// Channel weights come from here and stay fixed while minima are compared: every minimum is then
// judged on one and the same cost. (Weights re-estimated from each minimum's own residual make
// every minimum's cost ≈ N/2, and a worse minimum can win.)
//
// The noise of a channel is measured on the record's quiet stretch: the samples before the
// response starts on any of its channels (the line idles before the bite), less the last
// kQuietMargin of them, detrended by a straight line; σ² = Σ residual² / (m − 2). The response
// starts where a channel first leaves its initial level (median of its first samples) by
// kOnsetFraction of its largest excursion: at the noise levels (≤ 2 % of the peak) that
// is ≥ 5 σ, which noise alone does not reach. A response that rises slowly (a speed-controlled
// drive taking up the load over tenths of a second) began well before that: so the start is the
// earlier of that and the first sample beyond kOnsetSigmas times the RMS about the straight line
// through the first half of the samples before it. A record with fewer than kMinQuietSamples quiet
// samples (a logger started after the bite) falls back to the second differences over the
// window, σ = 1.4826 · median|Δ²y| / √6; the signal's own curvature biases that upwards on a
// coarsely sampled record, and the fit says so in a warning.
#pragma once

#include <string>
#include <vector>

#include "millkit/identify/oscillogram.h"

namespace millkit::identify {

inline constexpr double kOnsetFraction = 0.1;
inline constexpr double kOnsetSigmas = 5.0;
inline constexpr double kQuietMargin = 0.2;
inline constexpr int kMinQuietSamples = 16;
// No channel is trusted to be quieter than this fraction of its peak: about the resolution of a
// 14-bit recorder, and above a generated record's own accuracy (its filter runs on the
// generator's grid as linear between points, good to ~1e-5 of the peak; the fit's model filters
// exactly). A noise-free synthetic record would otherwise get weights that turn that error into a
// misfit.
inline constexpr double kNoiseFloorFraction = 1e-4;
// A torque beyond this is not a measurement (N·m; the largest mill drives carry ~1e7).
inline constexpr double kAbsurdTorque_Nm = 1e12;

// Lags of the autocorrelation kept for the residual's whiteness test (at most a quarter of the
// quiet stretch).
inline constexpr int kMaxCorrelationLags = 20;

struct ChannelNoise {
  double sigma_Nm = 0.0;
  // Autocorrelation of the detrended quiet stretch at lags 1, 2, …: what the noise itself looks
  // like (an anti-alias filter colours it), for the residual to be compared with. Empty for the
  // fallback.
  std::vector<double> autocorrelation;
  double dof = 0.0;  // degrees of freedom of σ² (for the residual test)
  bool from_quiet_stretch = false;
  int quiet_samples = 0;  // samples of the quiet stretch (0 for the fallback)
};

// Samples [0, end) of the record before its response starts (on any of the given columns), less
// the margin.
int QuietStretchEnd(const Oscillogram& record, const std::vector<int>& columns);

// Noise of one column; [begin, end) is the fit window (for the fallback).
ChannelNoise EstimateChannelNoise(const Oscillogram& record, int column, int quiet_end, int begin,
                                  int end);

// Sample autocorrelation of x (mean removed) at lags 1 … lags.
std::vector<double> Autocorrelation(const std::vector<double>& x, int lags);

// Why a column in [begin, end) cannot support a fit, or empty: values too large to be a torque,
// a flat (dead) channel. `sigma` is its noise estimate.
std::string DegenerateColumn(const Oscillogram& record, int column, int begin, int end,
                             double sigma_Nm);

}  // namespace millkit::identify
