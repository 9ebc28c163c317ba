#include "identify/record_noise.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "millkit/io/number_format.h"

namespace millkit::identify {
namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + static_cast<long>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

double Peak(const std::vector<double>& y) {
  double peak = 0.0;
  for (const double v : y) peak = std::max(peak, std::abs(v));
  return peak;
}

}  // namespace

std::vector<double> Autocorrelation(const std::vector<double>& x, int lags) {
  const int n = static_cast<int>(x.size());
  double mean = 0.0;
  for (const double v : x) mean += v;
  mean /= std::max(1, n);
  double variance = 0.0;
  for (const double v : x) variance += (v - mean) * (v - mean);
  std::vector<double> rho(std::max(0, lags), 0.0);
  if (!(variance > 0.0)) return rho;
  for (int lag = 1; lag <= lags && lag < n; ++lag) {
    double sum = 0.0;
    for (int k = lag; k < n; ++k) sum += (x[k] - mean) * (x[k - lag] - mean);
    rho[lag - 1] = sum / variance;
  }
  return rho;
}

namespace {

// The least-squares line through samples [0, m) of y (times centred for conditioning) and the
// residuals about it.
struct QuietLine {
  double time_mean = 0.0, level = 0.0, slope = 0.0;
  std::vector<double> residual;
  double At(double t) const { return level + slope * (t - time_mean); }
};

QuietLine FitQuietLine(const std::vector<double>& t, const std::vector<double>& y, int m) {
  QuietLine line;
  for (int k = 0; k < m; ++k) {
    line.time_mean += t[k];
    line.level += y[k];
  }
  line.time_mean /= m;
  line.level /= m;
  double stt = 0.0, sty = 0.0;
  for (int k = 0; k < m; ++k) {
    stt += (t[k] - line.time_mean) * (t[k] - line.time_mean);
    sty += (t[k] - line.time_mean) * (y[k] - line.level);
  }
  line.slope = stt > 0.0 ? sty / stt : 0.0;
  line.residual.resize(m);
  for (int k = 0; k < m; ++k) line.residual[k] = y[k] - line.At(t[k]);
  return line;
}

// Where one channel's response starts (n when it never leaves its initial level).
int ChannelOnset(const std::vector<double>& t, const std::vector<double>& y) {
  const int n = static_cast<int>(y.size());
  const double initial = Median(std::vector<double>(y.begin(), y.begin() + std::min(n, 5)));
  double excursion = 0.0;
  for (const double v : y) excursion = std::max(excursion, std::abs(v - initial));
  if (!(excursion > 0.0) || !std::isfinite(excursion)) return n;
  int onset = n;
  for (int k = 0; k < n; ++k) {
    if (std::abs(y[k] - initial) > kOnsetFraction * excursion) {
      onset = k;
      break;
    }
  }
  // A slow response reaches its first tenth long after it began, and the stretch before that
  // holds part of it. The first half of the stretch is the reference: the response starts where
  // the record leaves that half's straight line by kOnsetSigmas times its RMS.
  const int half = onset / 2;
  if (half < kMinQuietSamples) return onset;
  const QuietLine line = FitQuietLine(t, y, half);
  double sum = 0.0;
  for (const double r : line.residual) sum += r * r;
  // No channel is taken to be quieter than the noise floor (a noise-free record's roundoff).
  const double threshold =
      kOnsetSigmas * std::max(std::sqrt(sum / (half - 2)), kNoiseFloorFraction * excursion);
  for (int k = half; k < onset; ++k) {
    if (std::abs(y[k] - line.At(t[k])) > threshold) return k;
  }
  return onset;
}

}  // namespace

int QuietStretchEnd(const Oscillogram& record, const std::vector<int>& columns) {
  int onset = static_cast<int>(record.time_s.size());
  for (const int column : columns) {
    onset = std::min(onset, ChannelOnset(record.time_s, record.values[column]));
  }
  return static_cast<int>((1.0 - kQuietMargin) * onset);
}

ChannelNoise EstimateChannelNoise(const Oscillogram& record, int column, int quiet_end, int begin,
                                  int end) {
  const auto& y = record.values[column];
  const auto& t = record.time_s;
  ChannelNoise noise;
  if (quiet_end >= kMinQuietSamples) {
    const int m = quiet_end;
    const QuietLine line = FitQuietLine(t, y, m);
    double sum = 0.0;
    for (const double r : line.residual) sum += r * r;
    noise.autocorrelation = Autocorrelation(line.residual, std::min(kMaxCorrelationLags, m / 4));
    noise.sigma_Nm = std::sqrt(sum / (m - 2));
    noise.dof = m - 2;
    noise.from_quiet_stretch = true;
    noise.quiet_samples = m;
  } else {
    std::vector<double> second;
    for (int k = begin + 2; k < end; ++k)
      second.push_back(std::abs(y[k] - 2.0 * y[k - 1] + y[k - 2]));
    noise.sigma_Nm = 1.4826 * Median(second) / std::sqrt(6.0);
    // The median's efficiency for Gaussian data is 2/π.
    noise.dof = 0.637 * static_cast<double>(second.size());
  }
  const double floor = kNoiseFloorFraction * Peak(y);
  if (!(noise.sigma_Nm >= floor)) noise.sigma_Nm = floor;
  return noise;
}

std::string DegenerateColumn(const Oscillogram& record, int column, int begin, int end,
                             double sigma_Nm) {
  const auto& y = record.values[column];
  const std::string name = record.source + ", column " + record.channels[column];
  double low = std::numeric_limits<double>::infinity();
  double high = -low;
  for (int k = begin; k < end; ++k) {
    if (!std::isfinite(y[k]) || std::abs(y[k]) > kAbsurdTorque_Nm) {
      return name + ": value " + ShortNumber(y[k]) + " at t = " + ShortNumber(record.time_s[k]) +
             " s is not a torque (beyond " + ShortNumber(kAbsurdTorque_Nm) + " N*m)";
    }
    low = std::min(low, y[k]);
    high = std::max(high, y[k]);
  }
  if (!(high - low > 0.0)) {
    return name + ": the channel is constant (" + ShortNumber(low) +
           " N*m) over the window: a dead or disconnected gauge";
  }
  // A response must stand out of the noise; 10 σ peak to peak is a clear one.
  if (high - low < 10.0 * sigma_Nm) {
    return name + ": the channel varies by " + ShortNumber(high - low) + " N*m over the window, " +
           "less than 10 times its noise " + ShortNumber(sigma_Nm) + " N*m: no response to fit";
  }
  return "";
}

}  // namespace millkit::identify
