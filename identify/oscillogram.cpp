#include "millkit/identify/oscillogram.h"

#include <algorithm>
#include <cctype>

#include "millkit/identify/comtrade.h"
#include "millkit/identify/mat_record.h"
#include "millkit/io/csv.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::identify {
namespace {

std::string SeenColumns(const CsvTable& table) {
  std::string seen;
  for (size_t j = 0; j < table.columns.size(); ++j) {
    seen += (seen.empty() ? "" : ", ") + table.columns[j];
    if (!table.ids.empty() && table.ids[j] != table.columns[j]) seen += " " + table.ids[j];
  }
  return seen;
}

// The time column: the one named in the options, else the one without a signal ID in an iba
// export, else the one with a time name.
int TimeColumn(const CsvTable& table, const RecordOptions& options) {
  const std::string header = table.source + ": line " + std::to_string(table.header_line);
  if (!options.time_column.empty()) {
    for (size_t j = 0; j < table.columns.size(); ++j) {
      if (table.columns[j] == options.time_column ||
          (!table.ids.empty() && table.ids[j] == options.time_column)) {
        return static_cast<int>(j);
      }
    }
    throw InputError(header + ": no column '" + options.time_column +
                     "' (RecordOptions::time_column); seen: " + SeenColumns(table));
  }
  int time_column = -1;
  for (size_t j = 0; j < table.columns.size(); ++j) {
    const bool is_time =
        table.ids.empty() ? IsTimeColumnName(table.columns[j]) : !IsSignalId(table.ids[j]);
    if (!is_time) continue;
    if (time_column >= 0) {
      throw InputError(header + ": two time columns, '" + table.columns[time_column] + "' and '" +
                       table.columns[j] + "'; choose one with RecordOptions::time_column");
    }
    time_column = static_cast<int>(j);
  }
  if (time_column < 0) {
    throw InputError(
        header + ": no time column; expected one named 'time', 't', 'Time', " +
        "'time_s' or 'Time [s]' (in an iba export: the column without a signal " +
        "ID), or one chosen with RecordOptions::time_column (seen: " + SeenColumns(table) + ")");
  }
  return time_column;
}

Oscillogram FromTable(const CsvTable& table, const RecordOptions& options) {
  const std::string header = table.source + ": line " + std::to_string(table.header_line);
  const int time_column = TimeColumn(table, options);
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
      throw InputError(table.source + ": line " + std::to_string(table.units_line) +
                       " (units row): time unit '" + table.units[time_column] + "' is not s or ms");
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
    if (!table.ids.empty()) record.ids.push_back(table.ids[j]);
    record.values.push_back(table.ColumnValues(static_cast<int>(j)));
  }
  return record;
}

}  // namespace

bool IsTimeColumnName(const std::string& name) {
  std::string key;
  for (const char c : name) {
    if (c != ' ' && c != '\t')
      key += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return key == "time" || key == "t" || key == "time_s" || key == "time[s]" || key == "t[s]";
}

int Oscillogram::ChannelIndex(const std::string& name) const {
  const auto it = std::find(channels.begin(), channels.end(), name);
  if (it != channels.end()) return static_cast<int>(it - channels.begin());
  const auto id = std::find(ids.begin(), ids.end(), name);
  return id == ids.end() ? -1 : static_cast<int>(id - ids.begin());
}

std::pair<int, int> Oscillogram::WindowRange(double start, double end) const {
  const auto first = std::lower_bound(time_s.begin(), time_s.end(), start);
  const auto last = std::upper_bound(time_s.begin(), time_s.end(), end);
  return {static_cast<int>(first - time_s.begin()), static_cast<int>(last - time_s.begin())};
}

Oscillogram LoadOscillogram(const std::filesystem::path& path, const RecordOptions& options) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".cfg") {
    if (!options.time_column.empty()) {
      throw InputError(
          path.string() +
          ": RecordOptions::time_column does not apply to a COMTRADE record (its time comes " +
          "from the .cfg's sample rates or the .dat's time stamps)");
    }
    return LoadComtrade(path);
  }
  if (extension == ".mat") return LoadMatRecord(path, options);
  return FromTable(ReadCsv(path), options);
}

Oscillogram ParseOscillogram(const std::string& text, const std::string& source,
                             const RecordOptions& options) {
  return FromTable(ParseCsv(text, source), options);
}

std::vector<std::string> RecordLabels(const std::vector<Oscillogram>& records) {
  std::vector<std::string> labels;
  labels.reserve(records.size());
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
