#include "millkit/io/csv.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "millkit/io/input_error.h"
#include "millkit/io/input_file.h"

namespace millkit {
namespace {

std::string Trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return "";
  const auto last = s.find_last_not_of(" \t\r");
  return s.substr(first, last - first + 1);
}

std::string Line(const std::string& source, int line_number) {
  return source + ": line " + std::to_string(line_number);
}

// Splits a line at `separator` outside double quotes; a quoted cell loses its quotes ("" is one
// quote). Cells are trimmed of blanks.
std::vector<std::string> SplitCells(const std::string& line, char separator) {
  std::vector<std::string> cells;
  std::string cell;
  bool quoted = false;
  for (size_t k = 0; k < line.size(); ++k) {
    const char c = line[k];
    if (c == '"') {
      if (quoted && k + 1 < line.size() && line[k + 1] == '"') {
        cell += '"';
        ++k;
      } else {
        quoted = !quoted;
      }
    } else if (c == separator && !quoted) {
      cells.push_back(Trim(cell));
      cell.clear();
    } else if (c != '\r') {
      cell += c;
    }
  }
  cells.push_back(Trim(cell));
  return cells;
}

// The separator of a header line: the one of ';', tab and ',' that appears outside quotes.
char DetectSeparator(const std::string& header, const std::string& where) {
  std::string seen;
  bool quoted = false;
  for (const char c : header) {
    if (c == '"') quoted = !quoted;
    if (!quoted && (c == ';' || c == '\t' || c == ',') && seen.find(c) == std::string::npos) {
      seen += c;
    }
  }
  if (seen.size() > 1) {
    std::string names;
    for (const char c : seen)
      names += std::string(names.empty() ? "" : " and ") +
               (c == '\t' ? "tab" : std::string("'") + c + "'");
    throw InputError(where + ": the header mixes the separators " + names +
                     "; use one of ',', ';' or tab");
  }
  return seen.empty() ? ',' : seen[0];
}

// Text that reads as a number (NaN and infinities included); with a decimal comma allowed when the
// separator is not ','.
bool LooksNumeric(std::string cell, bool decimal_comma) {
  if (cell.empty()) return false;
  if (decimal_comma) {
    const auto comma = cell.find(',');
    if (comma != std::string::npos) cell[comma] = '.';
  }
  const char* begin = cell.data();
  const char* end = begin + cell.size();
  if (*begin == '+') ++begin;
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  return ptr == end && (ec == std::errc() || ec == std::errc::result_out_of_range);
}

// A finite number, or nothing; with a decimal comma allowed when the separator is not ','.
bool ParseNumber(std::string cell, bool decimal_comma, double* value) {
  if (cell.empty()) return false;
  if (decimal_comma) {
    const auto comma = cell.find(',');
    if (comma != std::string::npos) {
      if (cell.find('.') != std::string::npos || cell.find(',', comma + 1) != std::string::npos) {
        return false;
      }
      cell[comma] = '.';
    }
  }
  const char* begin = cell.data();
  const char* end = begin + cell.size();
  if (*begin == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, end, *value);
  return ec == std::errc() && ptr == end && std::isfinite(*value);
}

// Whether a header is an iba signal-ID row: IDs in every column but at most one.
bool IsSignalIdRow(const std::vector<std::string>& header) {
  int ids = 0;
  for (const auto& cell : header) ids += IsSignalId(cell) ? 1 : 0;
  return ids > 0 && ids + 1 >= static_cast<int>(header.size());
}

// The header and the data rows as text cells: the separator detected on the header (into
// *separator), a UTF-8 byte-order mark dropped, blank and '#' lines skipped, a separator that
// ends every line making no column. With `iba_ids`, a header of iba signal IDs may leave a cell
// empty (its name comes from the names row).
TextTable SplitTable(const std::string& text, const std::string& source, bool iba_ids,
                     char* separator_out) {
  TextTable table;
  table.source = source;
  std::istringstream in(text);
  std::string line;
  int line_number = 0;
  bool trailing_separator = false;
  char separator = ',';
  while (std::getline(in, line)) {
    ++line_number;
    // A UTF-8 byte-order mark (spreadsheet and logger exports) is not part of the first name.
    if (line_number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    if (table.header_line == 0) {
      separator = DetectSeparator(line, Line(source, line_number));
      std::vector<std::string> cells = SplitCells(line, separator);
      // A separator at the end of every line (some exports) makes no column.
      if (cells.size() > 1 && cells.back().empty()) {
        cells.pop_back();
        trailing_separator = true;
      }
      // An iba export may leave its time column's ID cell empty (named by its names row).
      const bool iba = iba_ids && IsSignalIdRow(cells);
      for (size_t j = 0; j < cells.size(); ++j) {
        if (cells[j].empty() && !iba) {
          throw InputError(Line(source, line_number) + ": header column " + std::to_string(j + 1) +
                           " has no name");
        }
      }
      table.columns = cells;
      table.header_line = line_number;
      continue;
    }
    std::vector<std::string> cells = SplitCells(line, separator);
    if (trailing_separator && cells.size() == table.columns.size() + 1 && cells.back().empty()) {
      cells.pop_back();
    }
    if (cells.size() != table.columns.size()) {
      throw InputError(Line(source, line_number) + ": " + std::to_string(cells.size()) +
                       " cells, the header has " + std::to_string(table.columns.size()));
    }
    table.rows.push_back(std::move(cells));
    table.line_numbers.push_back(line_number);
  }
  if (table.header_line == 0) throw InputError(source + ": empty file, expected a header row");
  if (separator_out != nullptr) *separator_out = separator;
  return table;
}

}  // namespace

bool IsSignalId(const std::string& cell) {
  size_t k = 0;
  const auto digits = [&cell, &k] {
    const size_t first = k;
    while (k < cell.size() && std::isdigit(static_cast<unsigned char>(cell[k]))) ++k;
    return k > first;
  };
  if (cell.empty() || cell[k++] != '[' || !digits()) return false;
  if (k >= cell.size() || (cell[k] != ':' && cell[k] != '.')) return false;
  const bool analog = cell[k++] == ':';
  if (!digits() || k >= cell.size() || cell[k++] != ']') return false;
  return k == cell.size() || (analog && cell.substr(k) == "_text");
}

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
  char separator = ',';
  TextTable cells = SplitTable(text, source, /*iba_ids=*/true, &separator);
  table.columns = std::move(cells.columns);
  table.header_line = cells.header_line;
  table.line_numbers = std::move(cells.line_numbers);
  // Data cells as text, decided per column below.
  std::vector<std::vector<std::string>> raw = std::move(cells.rows);

  const bool decimal_comma = separator != ',';
  double value = 0.0;
  // The rows after the header that hold no number: a units row in a plain table; names, units
  // and info rows in an iba export.
  std::vector<std::vector<std::string>> text_rows;
  std::vector<int> text_lines;
  while (!raw.empty()) {
    bool any_number = false;
    for (const auto& cell : raw.front())
      any_number = any_number || LooksNumeric(cell, decimal_comma);
    if (any_number) break;
    text_rows.push_back(std::move(raw.front()));
    text_lines.push_back(table.line_numbers.front());
    raw.erase(raw.begin());
    table.line_numbers.erase(table.line_numbers.begin());
  }
  if (IsSignalIdRow(table.columns)) {
    table.ids = table.columns;
    if (!text_rows.empty()) {
      for (size_t j = 0; j < table.columns.size(); ++j) {
        if (!text_rows[0][j].empty()) table.columns[j] = text_rows[0][j];
      }
    }
    for (size_t j = 0; j < table.columns.size(); ++j) {
      if (table.columns[j].empty()) table.columns[j] = "time";  // the one cell without an ID
    }
    if (text_rows.size() > 1) {
      table.units = text_rows[1];
      table.units_line = text_lines[1];
    }
    if (text_rows.size() > 2) {
      table.notes.push_back(Line(source, text_lines[2]) +
                            (text_rows.size() > 3 ? "-" + std::to_string(text_lines.back()) : "") +
                            ": iba info rows skipped");
    }
  } else if (text_rows.size() > 1) {
    throw InputError(Line(source, text_lines[1]) + ": a second row without numbers after the " +
                     "header (line " + std::to_string(table.header_line) +
                     "); a table has one header row and at most one units row (or is an iba " +
                     "export, whose first row holds signal IDs such as [3:12])");
  } else if (text_rows.size() == 1) {
    table.units = text_rows[0];
    table.units_line = text_lines[0];
  }
  // A text column (a coil ID, a comment) is one none of whose cells reads as a number: skipped,
  // with a note. Any other cell that is not a finite number is an error.
  std::vector<bool> keep(table.columns.size(), true);
  for (size_t j = 0; j < table.columns.size(); ++j) {
    bool any_number = false;
    for (const auto& row : raw) any_number = any_number || LooksNumeric(row[j], decimal_comma);
    if (!any_number && !raw.empty()) {
      keep[j] = false;
      table.notes.push_back(source + ": column '" + table.columns[j] +
                            "' holds no number and is skipped");
    }
  }
  std::vector<std::string> columns, units, ids;
  for (size_t j = 0; j < table.columns.size(); ++j) {
    if (!keep[j]) continue;
    columns.push_back(table.columns[j]);
    if (!table.units.empty()) units.push_back(table.units[j]);
    if (!table.ids.empty()) ids.push_back(table.ids[j]);
  }
  for (size_t i = 0; i < raw.size(); ++i) {
    std::vector<double> row;
    row.reserve(columns.size());
    for (size_t j = 0; j < raw[i].size(); ++j) {
      if (!keep[j]) continue;
      if (!ParseNumber(raw[i][j], decimal_comma, &value)) {
        throw InputError(Line(source, table.line_numbers[i]) + ", column '" + table.columns[j] +
                         "': '" + raw[i][j] + "' is not a finite number");
      }
      row.push_back(value);
    }
    table.rows.push_back(std::move(row));
  }
  table.columns = std::move(columns);
  table.units = std::move(units);
  table.ids = std::move(ids);
  return table;
}

CsvTable ReadCsv(const std::filesystem::path& path) {
  CheckInputFile(path);
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return ParseCsv(buffer.str(), path.string());
}

int TextTable::Find(const std::string& name) const {
  for (size_t j = 0; j < columns.size(); ++j) {
    if (columns[j] == name) return static_cast<int>(j);
  }
  return -1;
}

TextTable ParseTextCsv(const std::string& text, const std::string& source) {
  return SplitTable(text, source, /*iba_ids=*/false, nullptr);
}

TextTable ReadTextCsv(const std::filesystem::path& path) {
  CheckInputFile(path);
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return ParseTextCsv(buffer.str(), path.string());
}

void RequireUnits(const CsvTable& table,
                  const std::map<std::string, std::vector<std::string>>& accepted) {
  for (size_t j = 0; j < table.units.size() && j < table.columns.size(); ++j) {
    const std::string& unit = table.units[j];
    if (unit.empty()) continue;
    const auto it = accepted.find(table.columns[j]);
    std::string allowed;
    bool ok = false;
    if (it != accepted.end()) {
      for (const auto& a : it->second) {
        ok = ok || a == unit;
        allowed += (allowed.empty() ? "" : ", ") + a;
      }
    }
    if (ok) continue;
    throw InputError(
        table.source + ": line " + std::to_string(table.units_line) + " (units row), column '" +
        table.columns[j] + "': unit '" + unit + "' is not read here" +
        (allowed.empty() ? std::string("; give no units row") : "; this column takes " + allowed));
  }
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
