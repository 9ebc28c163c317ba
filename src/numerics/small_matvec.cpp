#include "numerics/small_matvec.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>

namespace millkit::numerics {
namespace {

// Four doubles; plain SSE2 pairs in the baseline clone, one AVX register in the v3 clone.
typedef double Lane __attribute__((vector_size(32)));

// Unaligned loads and stores through memcpy: no alignment or aliasing assumptions. Lanes pass by
// pointer or reference, as a 32-byte vector by value would change the baseline ABI.
inline void Load(Lane* lane, const double* p) { std::memcpy(lane, p, sizeof(Lane)); }
inline void Store(double* p, const Lane& lane) { std::memcpy(p, &lane, sizeof(Lane)); }

// y[0, 4 L) = A[0, 4 L) x for one block of L lanes (rows). Columns are taken in pairs into two
// sets of accumulators: half the dependency chain of one set.
template <int L>
__attribute__((always_inline)) inline void Block(const double* __restrict a, int ld, int cols,
                                                 const double* __restrict x, double* __restrict y) {
  Lane p[L], q[L], t;
  for (int l = 0; l < L; ++l) p[l] = q[l] = Lane{0.0, 0.0, 0.0, 0.0};
  int j = 0;
  for (; j + 2 <= cols; j += 2) {
    const double* c = a + static_cast<long>(j) * ld;
    const double* d = c + ld;
    for (std::ptrdiff_t l = 0; l < L; ++l) {
      Load(&t, c + 4 * l);
      p[l] += t * x[j];
      Load(&t, d + 4 * l);
      q[l] += t * x[j + 1];
    }
  }
  if (j < cols) {
    const double* c = a + static_cast<long>(j) * ld;
    for (std::ptrdiff_t l = 0; l < L; ++l) {
      Load(&t, c + 4 * l);
      p[l] += t * x[j];
    }
  }
  for (std::ptrdiff_t l = 0; l < L; ++l) Store(y + 4 * l, p[l] + q[l]);
}

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
__attribute__((target_clones("arch=x86-64-v3", "default")))
#endif
void Kernel(const double* __restrict a, int ld, int cols, const double* __restrict x,
            double* __restrict y) {
  int i0 = 0;
  for (; i0 + 16 <= ld; i0 += 16) Block<4>(a + i0, ld, cols, x, y + i0);
  switch ((ld - i0) / 4) {
    case 3:
      Block<3>(a + i0, ld, cols, x, y + i0);
      break;
    case 2:
      Block<2>(a + i0, ld, cols, x, y + i0);
      break;
    case 1:
      Block<1>(a + i0, ld, cols, x, y + i0);
      break;
    default:
      break;
  }
}

}  // namespace

void PaddedMatrix::Assign(const Eigen::MatrixXd& a) {
  rows_ = static_cast<int>(a.rows());
  cols_ = static_cast<int>(a.cols());
  ld_ = Padded(rows_);
  data_.assign(static_cast<size_t>(ld_) * cols_, 0.0);
  for (int j = 0; j < cols_; ++j) {
    for (int i = 0; i < rows_; ++i) data_[static_cast<size_t>(j) * ld_ + i] = a(i, j);
  }
}

void PaddedMatrix::CopyTo(Eigen::MatrixXd* a) const {
  a->resize(rows_, cols_);
  for (int j = 0; j < cols_; ++j) {
    for (int i = 0; i < rows_; ++i) (*a)(i, j) = data_[static_cast<size_t>(j) * ld_ + i];
  }
}

void PaddedMatrix::Apply(const double* x, double* y) const {
  Kernel(data_.data(), ld_, cols_, x, y);
}

void Multiply(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, Eigen::MatrixXd* c) {
  thread_local PaddedMatrix padded;
  thread_local std::vector<double> column;
  padded.Assign(a);
  column.resize(padded.ld());
  const int rows = static_cast<int>(a.rows());
  c->resize(rows, b.cols());
  for (int j = 0; j < b.cols(); ++j) {
    padded.Apply(b.col(j).data(), column.data());
    std::copy(column.begin(), column.begin() + rows, c->col(j).data());
  }
}

double SumAbs(const double* x, int padded_length) {
  double sum = 0.0;
  for (int i = 0; i < padded_length; ++i) sum += std::abs(x[i]);
  return sum;
}

double MaxAbsPadded(const double* x, int padded_length) {
  // Four independent chains (max compiles to maxsd/maxpd); x − x is 0 unless x is inf or NaN.
  double m0 = 0.0, m1 = 0.0, m2 = 0.0, m3 = 0.0, bad = 0.0;
  for (int i = 0; i < padded_length; i += 4) {
    const double a0 = std::abs(x[i]), a1 = std::abs(x[i + 1]);
    const double a2 = std::abs(x[i + 2]), a3 = std::abs(x[i + 3]);
    m0 = a0 > m0 ? a0 : m0;
    m1 = a1 > m1 ? a1 : m1;
    m2 = a2 > m2 ? a2 : m2;
    m3 = a3 > m3 ? a3 : m3;
    bad += (x[i] - x[i]) + (x[i + 1] - x[i + 1]) + (x[i + 2] - x[i + 2]) + (x[i + 3] - x[i + 3]);
  }
  if (bad != 0.0) return std::numeric_limits<double>::quiet_NaN();
  return std::max(std::max(m0, m1), std::max(m2, m3));
}

}  // namespace millkit::numerics
