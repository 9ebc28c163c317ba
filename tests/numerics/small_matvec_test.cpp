// numerics/small_matvec.h against Eigen's products.
#include "numerics/small_matvec.h"

#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <random>

using millkit::numerics::MaxAbsPadded;
using millkit::numerics::Multiply;
using millkit::numerics::PaddedMatrix;

namespace {
// Sums of at most 40 products of numbers below 1: a few ulps of 40.
constexpr double kProductTolerance = 1e-13;

Eigen::MatrixXd Random(int rows, int cols, std::mt19937* random) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Eigen::MatrixXd a(rows, cols);
  for (int j = 0; j < cols; ++j) {
    for (int i = 0; i < rows; ++i) a(i, j) = uniform(*random);
  }
  return a;
}
}  // namespace

TEST_CASE("The padded product equals Eigen's for every row and column count up to 40",
          "[numerics]") {
  std::mt19937 random(7);
  for (int rows = 1; rows <= 40; ++rows) {
    for (int cols : {1, 2, 3, 7, 15, 16, 17, 31}) {
      const Eigen::MatrixXd a = Random(rows, cols, &random);
      const Eigen::VectorXd x = Random(cols, 1, &random);
      const PaddedMatrix padded(a);
      REQUIRE(padded.ld() % 4 == 0);
      REQUIRE(padded.ld() >= rows);
      std::vector<double> y(padded.ld(), std::nan(""));
      padded.Apply(x.data(), y.data());
      const Eigen::VectorXd reference = a * x;
      for (int i = 0; i < rows; ++i) CHECK(std::abs(y[i] - reference[i]) <= kProductTolerance);
      for (int i = rows; i < padded.ld(); ++i) CHECK(y[i] == 0.0);  // padding rows
    }
  }
}

TEST_CASE("The small matrix product equals Eigen's", "[numerics]") {
  std::mt19937 random(11);
  const Eigen::MatrixXd a = Random(9, 15, &random), b = Random(15, 13, &random);
  Eigen::MatrixXd c;
  Multiply(a, b, &c);
  REQUIRE(c.rows() == 9);
  REQUIRE(c.cols() == 13);
  CHECK((c - a * b).cwiseAbs().maxCoeff() <= kProductTolerance);
}

TEST_CASE("MaxAbsPadded finds the largest magnitude and flags non-finite entries", "[numerics]") {
  std::vector<double> x = {0.5, -3.0, 2.0, 0.0, 1.0, -2.5, 0.25, 0.0};
  CHECK(MaxAbsPadded(x.data(), 8) == 3.0);
  CHECK(MaxAbsPadded(x.data(), 4) == 3.0);
  x[6] = std::numeric_limits<double>::infinity();
  CHECK(std::isnan(MaxAbsPadded(x.data(), 8)));
  x[6] = std::nan("");
  CHECK(std::isnan(MaxAbsPadded(x.data(), 8)));
}
