// The recorder's first-order anti-alias low-pass, y' = 2π f_c (x − y), applied to a signal known
// at sample times and linear between them (exact for that interpolation):
//   y_{k+1} = x_{k+1} − s/a + (y_k − x_k + s/a) e^{−a δ},  a = 2π f_c, δ = t_{k+1} − t_k,
//   s = (x_{k+1} − x_k)/δ.
// The filter starts settled (y_0 = x_0). Used by the record generator to make the defect and by the
// fit to model it, so a known filter does not bias the bite time by its group delay 1/(2π f_c).
#pragma once

#include <cmath>
#include <vector>

namespace millkit::identify {

inline void FirstOrderLowPass(double cutoff_Hz, const std::vector<double>& t,
                              std::vector<double>* x) {
  if (cutoff_Hz <= 0.0 || x->empty()) return;
  constexpr double kTwoPi = 6.283185307179586476925;
  const double a = kTwoPi * cutoff_Hz;
  double y = (*x)[0];
  double previous = (*x)[0];
  for (size_t k = 1; k < x->size(); ++k) {
    const double delta = t[k] - t[k - 1];
    const double current = (*x)[k];
    const double slope_term = (current - previous) / (delta * a);
    y = current - slope_term + (y - previous + slope_term) * std::exp(-a * delta);
    previous = current;
    (*x)[k] = y;
  }
}

}  // namespace millkit::identify
