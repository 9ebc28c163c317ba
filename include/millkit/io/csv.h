// Numeric tables as spreadsheets and data loggers export them: a header row of column names, an
// optional units row, then rows of numbers. Accepted dialects: a UTF-8 byte-order mark; ',', ';'
// or tab as the separator (the one the header uses; a header mixing them is an error); a decimal
// comma when the separator is not ','; quoted cells ("" for a quote); a separator at the end of
// every line; CRLF line ends; blank lines and '#' comment lines. A column none of whose cells is
// a number (a coil ID) is skipped with a note. Any other cell that is not a finite number is an
// InputError naming the file, the line (1-based) and the column.
//
// The ASCII export of iba loggers is read too: its first row holds signal IDs ([module:channel]
// for analog, [module.channel] for digital, [module:channel]_text for text signals) in every
// column but at most one (the time column). The rows after it that hold no number are, in this
// order, the signal names, their units and any number of info rows (skipped with a note). A
// column is then named by its signal name (its ID when the name is empty) and keeps its ID.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace millkit {

struct CsvTable {
  std::string source;                     // file name, for error messages
  std::vector<std::string> columns;       // header names, trimmed, unquoted
  std::vector<std::string> units;         // from a units row (empty when there is none)
  std::vector<std::string> ids;           // iba signal IDs per column (empty: not an iba file)
  std::vector<std::string> notes;         // what the reader skipped, for the user
  int header_line = 0;                    // line of the header row (1-based)
  int units_line = 0;                     // line of the units row (0: none)
  std::vector<std::vector<double>> rows;  // rows[i][j]: data row i, column j
  std::vector<int> line_numbers;          // line in the file of each data row (1-based)

  // Index of the column named `name`; throws InputError naming the file when it is absent.
  int Column(const std::string& name) const;
  bool HasColumn(const std::string& name) const;
  std::vector<double> ColumnValues(int column) const;
};

// True for an iba signal ID: [m:c], [m.c] or [m:c]_text with decimal m and c.
bool IsSignalId(const std::string& cell);

// Reads a numeric CSV. Blank lines are skipped; lines starting with '#' are comments.
// Throws InputError (file, line, column named) on an unreadable file, a missing header, a row with
// the wrong number of cells, or a cell that is not a finite number.
CsvTable ReadCsv(const std::filesystem::path& path);

// Parses CSV text (used by ReadCsv and by tests); `source` names it in error messages.
CsvTable ParseCsv(const std::string& text, const std::string& source);

// A units row is honoured only where its reader checks it. Throws InputError (file, units row,
// column) unless every column's unit is empty or one of accepted[column name]; a column missing
// from `accepted` accepts no unit. Tables without a units row pass.
void RequireUnits(const CsvTable& table,
                  const std::map<std::string, std::vector<std::string>>& accepted);

// Throws InputError unless column `column` strictly increases down the table (row named).
void RequireStrictlyIncreasing(const CsvTable& table, int column);

// A table of text cells (a manifest listing files, dates and names): the same dialect as ReadCsv
// (byte-order mark, ',', ';' or tab, quotes, trailing separators, CRLF, blank and '#' lines),
// every cell kept as trimmed, unquoted text. No units row, no iba export.
struct TextTable {
  std::string source;
  std::vector<std::string> columns;
  int header_line = 0;
  std::vector<std::vector<std::string>> rows;  // rows[i][j]: data row i, column j
  std::vector<int> line_numbers;               // line in the file of each data row (1-based)

  // Index of the column named `name`, −1 when absent.
  int Find(const std::string& name) const;
};

// Throws InputError (file and line named) on an unreadable or empty file, a header cell without
// a name, or a row with the wrong number of cells.
TextTable ReadTextCsv(const std::filesystem::path& path);
TextTable ParseTextCsv(const std::string& text, const std::string& source);

}  // namespace millkit
