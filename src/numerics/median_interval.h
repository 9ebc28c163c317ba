// The median interval between sorted times: a record's or an output grid's sampling interval,
// which a stray long or short gap does not move.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace millkit::numerics {

// The median of times[k] − times[k − 1]; `fallback` when there are fewer than two times.
inline double MedianInterval(const std::vector<double>& times, double fallback) {
  if (times.size() < 2) return fallback;
  std::vector<double> gaps(times.size() - 1);
  for (size_t k = 1; k < times.size(); ++k) gaps[k - 1] = times[k] - times[k - 1];
  const auto middle = gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2);
  std::nth_element(gaps.begin(), middle, gaps.end());
  return *middle;
}

}  // namespace millkit::numerics
