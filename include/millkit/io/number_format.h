// The one number format module: every number MillKit writes into a message, a CSV cell, a JSON
// note or a plot label goes through these. Results meant to be read back use the shortest text
// that reads back to the same double (FormatNumber, AppendNumber).
#pragma once

#include <string>

namespace millkit {

// Number formatting for messages: shortest round-trip representation.
std::string FormatNumber(double value);
// `digits` significant digits (3 by default), for messages, reports and fixed-width CSV cells;
// "nan" for any NaN (never "-nan").
std::string ShortNumber(double value, int digits = 3);
// `decimals` digits after the point ("%.*f"), for tables printed to the terminal.
std::string FixedNumber(double value, int decimals);
// A value and its standard error with the digits the error supports: the error to two significant
// digits, the value rounded to the same place ("12346 ± 49", "0.02351 ± 0.00021"), with a shared
// exponent beyond 10^-3 … 10^5 ("(1.1512 ± 0.0034)e7"). When the standard error is not finite and
// positive: the value alone to `digits` significant digits (ShortNumber).
std::string ValueWithError(double value, double standard_error, int digits = 4);
// Appends the same shortest round-trip text to `text` without a temporary (CSV writers).
void AppendNumber(double value, std::string* text);

}  // namespace millkit
