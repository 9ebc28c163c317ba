// Numeric CSV tables: a header row of column names, then rows of numbers (SPEC §3).
// Every cell must parse as a finite number; a bad cell is an InputError naming the file, the row
// (1-based line number in the file) and the column.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace millkit {

struct CsvTable {
  std::string source;                      // file name, for error messages
  std::vector<std::string> columns;        // header names, trimmed
  std::vector<std::vector<double>> rows;   // rows[i][j]: data row i, column j
  std::vector<int> line_numbers;           // line in the file of each data row (1-based)

  // Index of the column named `name`; throws InputError naming the file when it is absent.
  int Column(const std::string& name) const;
  bool HasColumn(const std::string& name) const;
  std::vector<double> ColumnValues(int column) const;
};

// Reads a numeric CSV. Blank lines are skipped; lines starting with '#' are comments.
// Throws InputError (file, line, column named) on an unreadable file, a missing header, a row with
// the wrong number of cells, or a cell that is not a finite number.
CsvTable ReadCsv(const std::filesystem::path& path);

// Parses CSV text (used by ReadCsv and by tests); `source` names it in error messages.
CsvTable ParseCsv(const std::string& text, const std::string& source);

// Throws InputError unless column `column` strictly increases down the table (row named).
void RequireStrictlyIncreasing(const CsvTable& table, int column);

}  // namespace millkit
