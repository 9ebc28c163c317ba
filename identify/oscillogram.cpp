#include "identify/oscillogram.h"

#include <algorithm>
#include <cctype>

#include "identify/comtrade.h"
#include "io/csv.h"
#include "io/input_error.h"
#include "io/toml_section.h"

namespace millkit::identify {
namespace {

// The time column's accepted names, compared without case and blanks.
bool IsTimeName(std::string name) {
  std::string key;
  for (const char c : name) {
    if (c != ' ' && c != '\t')
      key += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return key == "time" || key == "t" || key == "time_s" || key == "time[s]" || key == "t[s]";
}

Oscillogram FromTable(const CsvTable& table) {
  const std::string header = table.source + ": line " + std::to_string(table.header_line);
  int time_column = -1;
  for (size_t j = 0; j < table.columns.size(); ++j) {
    if (!IsTimeName(table.columns[j])) continue;
    if (time_column >= 0) {
      throw InputError(header + ": two time columns, '" + table.columns[time_column] + "' and '" +
                       table.columns[j] + "'");
    }
    time_column = static_cast<int>(j);
  }
  if (time_column < 0) {
    std::string seen;
    for (const auto& c : table.columns) seen += (seen.empty() ? "" : ", ") + c;
    throw InputError(header +
                     ": no time column; expected one named 'time', 't', 'Time', "
                     "'time_s' or 'Time [s]' (seen: " +
                     seen + ")");
  }
  if (table.columns.size() < 2) {
    throw InputError(header + ": no channel column besides '" + table.columns[time_column] + "'");
  }
  if (static_cast<int>(table.rows.size()) < kMinRecordSamples) {
    throw InputError(table.source + ": " + std::to_string(table.rows.size()) +
                     " samples; a record needs at least " + std::to_string(kMinRecordSamples));
  }
  // Time in s, or in ms when its units row says so.
  double time_scale = 1.0;
  if (!table.units.empty()) {
    std::string unit = table.units[time_column];
    unit.erase(std::remove_if(unit.begin(), unit.end(),
                              [](char c) { return c == '[' || c == ']' || c == ' '; }),
               unit.end());
    if (unit == "ms") {
      time_scale = 1e-3;
    } else if (!unit.empty() && unit != "s") {
      throw InputError(table.source + ": units row: time unit '" + table.units[time_column] +
                       "' is not s or ms");
    }
  }
  RequireStrictlyIncreasing(table, time_column);
  Oscillogram record;
  record.source = table.source;
  record.time_s = table.ColumnValues(time_column);
  for (double& t : record.time_s) t *= time_scale;
  record.line_numbers = table.line_numbers;
  record.notes = table.notes;
  for (size_t j = 0; j < table.columns.size(); ++j) {
    if (static_cast<int>(j) == time_column) continue;
    if (std::find(record.channels.begin(), record.channels.end(), table.columns[j]) !=
        record.channels.end()) {
      throw InputError(header + ": column '" + table.columns[j] + "' appears twice");
    }
    record.channels.push_back(table.columns[j]);
    record.units.push_back(table.units.empty() ? "" : table.units[j]);
    record.values.push_back(table.ColumnValues(static_cast<int>(j)));
  }
  return record;
}

}  // namespace

int Oscillogram::ChannelIndex(const std::string& name) const {
  const auto it = std::find(channels.begin(), channels.end(), name);
  return it == channels.end() ? -1 : static_cast<int>(it - channels.begin());
}

std::pair<int, int> Oscillogram::WindowRange(double start, double end) const {
  const auto first = std::lower_bound(time_s.begin(), time_s.end(), start);
  const auto last = std::upper_bound(time_s.begin(), time_s.end(), end);
  return {static_cast<int>(first - time_s.begin()), static_cast<int>(last - time_s.begin())};
}

Oscillogram LoadOscillogram(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".cfg") return LoadComtrade(path);
  return FromTable(ReadCsv(path));
}

Oscillogram ParseOscillogram(const std::string& text, const std::string& source) {
  return FromTable(ParseCsv(text, source));
}

std::vector<std::string> RecordLabels(const std::vector<Oscillogram>& records) {
  std::vector<std::string> labels;
  for (const auto& record : records) {
    labels.push_back(std::filesystem::path(record.source).stem().string());
  }
  std::vector<std::string> unique = labels;
  for (size_t i = 0; i < labels.size(); ++i) {
    if (std::count(labels.begin(), labels.end(), labels[i]) > 1) {
      unique[i].push_back('#');
      unique[i].append(std::to_string(i + 1));
    }
  }
  return unique;
}

std::string FormatOscillogram(const Oscillogram& record) {
  std::string text = "time";
  for (const auto& name : record.channels) text += "," + name;
  text += '\n';
  const auto append = [&text](double value) { AppendNumber(value, &text); };
  for (size_t k = 0; k < record.time_s.size(); ++k) {
    append(record.time_s[k]);
    for (const auto& channel : record.values) {
      text += ',';
      append(channel[k]);
    }
    text += '\n';
  }
  return text;
}

}  // namespace millkit::identify
