#include "millkit/io/number_format.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>

namespace millkit {

std::string FormatNumber(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

std::string ShortNumber(double value, int digits) {
  if (std::isnan(value)) return "nan";
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*g", digits, value);
  return buffer;
}

std::string ValueWithError(double value, double standard_error, int digits) {
  if (!std::isfinite(value) || !std::isfinite(standard_error) || !(standard_error > 0.0)) {
    return ShortNumber(value, digits);
  }
  const int place = static_cast<int>(std::floor(std::log10(standard_error))) - 1;
  const double unit = std::pow(10.0, place);
  const double error = std::round(standard_error / unit) * unit;
  const double rounded = std::round(value / unit) * unit + 0.0;  // + 0.0: no "-0"
  const int exponent = static_cast<int>(std::floor(std::log10(std::max(std::abs(rounded), error))));
  char buffer[96];
  if (exponent >= 6 || exponent <= -4) {
    const double scale = std::pow(10.0, exponent);
    std::snprintf(buffer, sizeof(buffer), "(%.*f \u00b1 %.*f)e%d", exponent - place,
                  rounded / scale + 0.0, exponent - place, error / scale, exponent);
  } else {
    const int decimals = std::max(0, -place);
    std::snprintf(buffer, sizeof(buffer), "%.*f \u00b1 %.*f", decimals, rounded, decimals, error);
  }
  return buffer;
}

std::string FixedNumber(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

void AppendNumber(double value, std::string* text) {
  char buffer[64];
  text->append(buffer, std::to_chars(buffer, buffer + sizeof(buffer), value).ptr);
}

}  // namespace millkit
