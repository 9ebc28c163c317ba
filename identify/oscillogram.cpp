#include "identify/oscillogram.h"

#include <algorithm>

#include "io/csv.h"
#include "io/input_error.h"
#include "io/toml_section.h"

namespace millkit::identify {
namespace {

Oscillogram FromTable(const CsvTable& table) {
  if (table.columns.empty() || table.columns[0] != "time") {
    throw InputError(table.source + ": line 1: the first column must be named 'time' (SPEC §3)");
  }
  if (table.columns.size() < 2) {
    throw InputError(table.source + ": line 1: no channel column after 'time'");
  }
  if (static_cast<int>(table.rows.size()) < kMinRecordSamples) {
    throw InputError(table.source + ": " + std::to_string(table.rows.size()) +
                     " samples; a record needs at least " + std::to_string(kMinRecordSamples));
  }
  RequireStrictlyIncreasing(table, 0);
  Oscillogram record;
  record.source = table.source;
  record.time_s = table.ColumnValues(0);
  record.line_numbers = table.line_numbers;
  for (size_t j = 1; j < table.columns.size(); ++j) {
    if (std::find(record.channels.begin(), record.channels.end(), table.columns[j]) !=
        record.channels.end()) {
      throw InputError(table.source + ": line 1: column '" + table.columns[j] + "' appears twice");
    }
    record.channels.push_back(table.columns[j]);
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

Oscillogram LoadOscillogram(const std::filesystem::path& path) { return FromTable(ReadCsv(path)); }

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
