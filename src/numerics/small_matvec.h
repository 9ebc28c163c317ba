// y = A x for the small dense matrices on the hot path of the exact drive-line solver (tens of
// rows, 10–30 columns, one product per output step). At these sizes Eigen's dynamic-size gemv
// spends most of its time in set-up and remainder loops; this kernel keeps A column-major with the
// rows padded to a multiple of 4 and accumulates blocks of 16 rows in registers. It is compiled for
// x86-64-v3 (AVX2, FMA) and for the baseline, chosen once at load time (GCC target_clones); the
// two round differently in the last bit (FMA), so results are reproducible per machine type.
#pragma once

#include <Eigen/Dense>
#include <vector>

namespace millkit::numerics {

class PaddedMatrix {
 public:
  PaddedMatrix() = default;
  explicit PaddedMatrix(const Eigen::MatrixXd& a) { Assign(a); }

  // Copies a (reusing the storage when the size allows).
  void Assign(const Eigen::MatrixXd& a);

  int rows() const { return rows_; }
  int cols() const { return cols_; }
  // Rows rounded up to a multiple of 4: the length Apply writes.
  int ld() const { return ld_; }

  // y[0, ld) = A x, x with cols() entries. The padding rows of y get 0. x and y must not overlap.
  void Apply(const double* x, double* y) const;

  // The matrix without padding (reuses *a's storage when the size allows).
  void CopyTo(Eigen::MatrixXd* a) const;

  // Number of doubles Apply writes for a matrix of `rows` rows.
  static int Padded(int rows) { return (rows + 3) / 4 * 4; }

 private:
  int rows_ = 0, cols_ = 0, ld_ = 0;
  std::vector<double> data_;  // ld_ × cols_, column-major, padding rows zero
};

// c = a b for small dense matrices, one column of b at a time through the same kernel (several
// times faster than Eigen's blocked product below about 30 × 30). c must not alias a or b.
void Multiply(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, Eigen::MatrixXd* c);

// Σ |x_i| over x[0, padded_length), padded_length a multiple of 4.
double SumAbs(const double* x, int padded_length);

// max |x_i| over x[0, padded_length), padded_length a multiple of 4; NaN when an entry is not
// finite.
double MaxAbsPadded(const double* x, int padded_length);

}  // namespace millkit::numerics
