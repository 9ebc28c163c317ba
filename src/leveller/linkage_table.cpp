#include "millkit/leveller/linkage_table.h"

#include <utility>

#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::leveller {
namespace {

// Cells keep 15 significant digits (1e-12 mm / 1e-12 deg): enough to carry the 1e-9 mm inverse
// accuracy through a file.
std::string Cell(double value) { return ShortNumber(value, 15); }

// Appends `cell` to a CSV line, after a comma unless it is the first.
void AppendCell(const std::string& cell, std::string* line) {
  if (!line->empty()) line->push_back(',');
  line->append(cell);
}

// Header of the input plus the added columns (RequireNoOutputColumns checked them).
std::string HeaderWith(const CsvTable& table, const std::vector<std::string>& added) {
  std::string header;
  for (const auto& c : table.columns) AppendCell(c, &header);
  for (const auto& c : added) AppendCell(c, &header);
  header.push_back('\n');
  return header;
}

// The input row, then the added cells; `status` (when not empty) as the last cell.
std::string RowWith(const std::vector<double>& row, const std::vector<double>& added,
                    const std::string& status = "") {
  std::string line;
  for (double v : row) AppendCell(Cell(v), &line);
  for (double v : added) AppendCell(Cell(v), &line);
  if (!status.empty()) AppendCell(status, &line);
  line.push_back('\n');
  return line;
}

const std::vector<std::string>& ForwardOutputColumns() {
  static const std::vector<std::string> columns{"y1_mm", "y2_mm", "y3_mm"};
  return columns;
}

}  // namespace

void CheckWorkingRange(const LinkageGeometry& geometry, double beta1_deg, double beta2_deg,
                       const std::string& where) {
  for (const auto& [name, value] :
       {std::pair{"beta1_deg", beta1_deg}, std::pair{"beta2_deg", beta2_deg}}) {
    if (value < geometry.beta_min_deg || value > geometry.beta_max_deg) {
      throw InputError(where + ": column '" + name + "' = " + FormatNumber(value) +
                       " outside the working range [" + FormatNumber(geometry.beta_min_deg) + ", " +
                       FormatNumber(geometry.beta_max_deg) + "] deg");
    }
  }
}

void CheckCylinderRanges(const HydraulicRange& cylinders, double ah_mm, double bg_mm,
                         const std::string& where) {
  if (ah_mm < cylinders.ah_min_mm || ah_mm > cylinders.ah_max_mm || bg_mm < cylinders.bg_min_mm ||
      bg_mm > cylinders.bg_max_mm) {
    throw InputError(where + ": (ah_mm, bg_mm) = (" + FormatNumber(ah_mm) + ", " +
                     FormatNumber(bg_mm) + ") outside the cylinder ranges [" +
                     FormatNumber(cylinders.ah_min_mm) + ", " + FormatNumber(cylinders.ah_max_mm) +
                     "] x [" + FormatNumber(cylinders.bg_min_mm) + ", " +
                     FormatNumber(cylinders.bg_max_mm) + "] mm");
  }
}

void RequireNoOutputColumns(const CsvTable& input, const std::vector<std::string>& outputs) {
  for (const auto& c : outputs) {
    if (input.HasColumn(c)) {
      throw InputError(input.source + ": column '" + c + "' is an output column; remove it");
    }
  }
}

void RequireRows(const CsvTable& input, const std::string& what) {
  if (input.rows.empty()) throw InputError(input.source + ": no " + what + " listed");
}

std::string RowLocation(const CsvTable& table, std::size_t row) {
  return table.source + ":" + std::to_string(table.line_numbers[row]);
}

ForwardTable ComputeForwardTable(const CsvTable& input, const LevellerConfig& config,
                                 LinkageDrive drive) {
  const bool hydraulic = drive == LinkageDrive::kHydraulic;
  const Linkage linkage(config.linkage);
  const int c1 = input.Column(hydraulic ? "ah_mm" : "beta1_deg");
  const int c2 = input.Column(hydraulic ? "bg_mm" : "beta2_deg");
  RequireNoOutputColumns(input, ForwardOutputColumns());
  RequireRows(input, hydraulic ? "cylinder lengths" : "eccentric angles");
  ForwardTable table{input, {}};
  for (std::size_t r = 0; r < input.rows.size(); ++r) {
    const double u = input.rows[r][c1];
    const double v = input.rows[r][c2];
    Intermesh<double> y{};
    bool assembled = false;
    if (hydraulic) {
      CheckCylinderRanges(config.hydraulic, u, v, RowLocation(input, r));
      assembled = linkage.ForwardLengths(u, v, &y);
    } else {
      CheckWorkingRange(config.linkage, u, v, RowLocation(input, r));
      assembled = linkage.Forward(u, v, &y);
    }
    if (!assembled) {
      throw InputError(RowLocation(input, r) + ": the linkage does not assemble at this input");
    }
    table.intermesh.push_back(y);
  }
  return table;
}

std::string FormatForwardTable(const ForwardTable& table) {
  std::string text = HeaderWith(table.input, ForwardOutputColumns());
  for (std::size_t r = 0; r < table.input.rows.size(); ++r) {
    const auto& y = table.intermesh[r];
    text += RowWith(table.input.rows[r], {y.y1, y.y2, y.y3});
  }
  return text;
}

int InverseTable::NotOkCount() const {
  int count = 0;
  for (const auto& row : rows) count += row.ok() ? 0 : 1;
  return count;
}

std::vector<std::string> InverseOutputColumns(LinkageDrive drive) {
  std::vector<std::string> columns =
      drive == LinkageDrive::kHydraulic
          ? std::vector<std::string>{"ah_mm", "bg_mm", "y3_mm", "residual_mm"}
          : std::vector<std::string>{"beta1_deg", "beta2_deg", "y3_mm", "residual_mm",
                                     "accuracy_mm"};
  for (const char* c : {"nearest_y1_mm", "nearest_y2_mm", "status"}) columns.emplace_back(c);
  return columns;
}

std::string FormatInverseTable(const InverseTable& table) {
  const bool hydraulic = table.drive == LinkageDrive::kHydraulic;
  std::string text = HeaderWith(table.input, InverseOutputColumns(table.drive));
  for (std::size_t r = 0; r < table.input.rows.size(); ++r) {
    const InverseRow& row = table.rows[r];
    const std::vector<double> cells =
        hydraulic ? std::vector<double>{row.ah_mm,       row.bg_mm,         row.y3_mm,
                                        row.residual_mm, row.nearest_y1_mm, row.nearest_y2_mm}
                  : std::vector<double>{row.beta1_deg,    row.beta2_deg,   row.y3_mm,
                                        row.residual_mm,  row.accuracy_mm, row.nearest_y1_mm,
                                        row.nearest_y2_mm};
    text += RowWith(table.input.rows[r], cells, row.status);
  }
  return text;
}

}  // namespace millkit::leveller
