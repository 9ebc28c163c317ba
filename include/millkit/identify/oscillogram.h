// Measured oscillograms: a table (millkit/io/csv.h: the dialects of spreadsheet and logger exports)
// with a time column named `time`, `t`, `Time`, `time_s` or `Time [s]` (s, or ms when a units row
// says so; strictly increasing; it need not start at 0) and further columns named channels
// (strain-gauge torque, N·m after calibration). The user reference is docs/identify.md.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace millkit::identify {

struct Oscillogram {
  std::string source;  // file name, for messages
  std::vector<double> time_s;
  std::vector<std::string> channels;        // column names after `time`
  std::vector<std::vector<double>> values;  // values[channel][sample]
  std::vector<int> line_numbers;            // file line of each sample (1-based)
  std::vector<std::string> units;           // per channel, from a units row ("" when none)
  std::vector<std::string> ids;             // per channel, iba signal IDs (empty: none)
  std::vector<std::string> notes;           // what the reader skipped (text columns)

  // The channel with this name, or this iba signal ID; −1 when absent.
  int ChannelIndex(const std::string& name) const;
  // Indices of the samples with time in [start, end].
  std::pair<int, int> WindowRange(double start, double end) const;
};

// Whether a column name is one of the time column's: `time`, `t`, `Time`, `time_s`, `Time [s]`
// (compared without case and blanks).
bool IsTimeColumnName(const std::string& name);

// How to read a record.
struct RecordOptions {
  // The time column (or MAT variable) by name or iba signal ID; empty: the one named `time`, `t`,
  // `Time`, `time_s` or `Time [s]` (in an iba export: the column without a signal ID).
  std::string time_column;
};

// Fewer samples than this cannot constrain a fit.
inline constexpr int kMinRecordSamples = 16;

// Reads and checks a record: a table (above), or a COMTRADE .cfg with its .dat
// (include/millkit/identify/comtrade.h). Throws InputError naming the file, row and column for a
// cell that is not a finite number, a time that does not strictly increase, a first column not
// named `time`, no channel column, or fewer than kMinRecordSamples rows.
Oscillogram LoadOscillogram(const std::filesystem::path& path, const RecordOptions& options = {});
Oscillogram ParseOscillogram(const std::string& text, const std::string& source,
                             const RecordOptions& options = {});

// Short names of records fitted together, for parameter and channel names: each file's stem,
// with #k (1-based position) appended where two stems are equal.
std::vector<std::string> RecordLabels(const std::vector<Oscillogram>& records);

// CSV text of a record (shortest round-trip numbers); used by the record generator.
std::string FormatOscillogram(const Oscillogram& record);

}  // namespace millkit::identify
