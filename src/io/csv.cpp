#include "io/csv.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "io/input_error.h"

namespace millkit {
namespace {

std::string Trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\"");
  if (first == std::string::npos) return "";
  const auto last = s.find_last_not_of(" \t\r\"");
  return s.substr(first, last - first + 1);
}

std::vector<std::string> SplitCells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(Trim(cell));
  if (!line.empty() && line.back() == ',') cells.push_back("");
  return cells;
}

}  // namespace

int CsvTable::Column(const std::string& name) const {
  for (size_t j = 0; j < columns.size(); ++j) {
    if (columns[j] == name) return static_cast<int>(j);
  }
  throw InputError(source + ": missing column '" + name + "'");
}

bool CsvTable::HasColumn(const std::string& name) const {
  for (const auto& c : columns) {
    if (c == name) return true;
  }
  return false;
}

std::vector<double> CsvTable::ColumnValues(int column) const {
  std::vector<double> values;
  values.reserve(rows.size());
  for (const auto& row : rows) values.push_back(row[column]);
  return values;
}

CsvTable ParseCsv(const std::string& text, const std::string& source) {
  CsvTable table;
  table.source = source;
  std::istringstream in(text);
  std::string line;
  int line_number = 0;
  bool have_header = false;
  while (std::getline(in, line)) {
    ++line_number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    std::vector<std::string> cells = SplitCells(line);
    if (!have_header) {
      for (size_t j = 0; j < cells.size(); ++j) {
        if (cells[j].empty()) {
          throw InputError(source + ": line " + std::to_string(line_number) + ": header column " +
                           std::to_string(j + 1) + " has no name");
        }
      }
      table.columns = cells;
      have_header = true;
      continue;
    }
    if (cells.size() != table.columns.size()) {
      throw InputError(source + ": line " + std::to_string(line_number) + ": " +
                       std::to_string(cells.size()) + " cells, the header has " +
                       std::to_string(table.columns.size()));
    }
    std::vector<double> row(cells.size());
    for (size_t j = 0; j < cells.size(); ++j) {
      const std::string& cell = cells[j];
      double value = 0.0;
      const char* begin = cell.data();
      const char* end = begin + cell.size();
      if (!cell.empty() && *begin == '+') ++begin;
      const auto [ptr, ec] = std::from_chars(begin, end, value);
      if (cell.empty() || ec != std::errc() || ptr != end || !std::isfinite(value)) {
        throw InputError(source + ": line " + std::to_string(line_number) + ", column '" +
                         table.columns[j] + "': '" + cell + "' is not a finite number");
      }
      row[j] = value;
    }
    table.rows.push_back(std::move(row));
    table.line_numbers.push_back(line_number);
  }
  if (!have_header) throw InputError(source + ": empty file, expected a header row");
  return table;
}

CsvTable ReadCsv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return ParseCsv(buffer.str(), path.string());
}

void RequireStrictlyIncreasing(const CsvTable& table, int column) {
  for (size_t i = 1; i < table.rows.size(); ++i) {
    if (!(table.rows[i][column] > table.rows[i - 1][column])) {
      throw InputError(table.source + ": line " + std::to_string(table.line_numbers[i]) +
                       ", column '" + table.columns[column] +
                       "': must increase strictly (previous row has " +
                       std::to_string(table.rows[i - 1][column]) + ")");
    }
  }
}

}  // namespace millkit
