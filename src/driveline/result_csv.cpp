#include "millkit/driveline/result_csv.h"

#include <cmath>
#include <cstdio>

#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::driveline {

std::vector<ResultColumn> AllResultColumns(const Scene& scene) {
  std::vector<ResultColumn> columns;
  for (size_t l = 0; l < scene.links.size(); ++l) {
    columns.push_back({scene.links[l].name, OutputBlock::kTorque, static_cast<int>(l)});
  }
  for (size_t i = 0; i < scene.masses.size(); ++i) {
    columns.push_back({"speed." + scene.masses[i].name, OutputBlock::kSpeed, static_cast<int>(i)});
  }
  for (size_t l = 0; l < scene.links.size(); ++l) {
    columns.push_back({"twist." + scene.links[l].name, OutputBlock::kTwist, static_cast<int>(l)});
  }
  return columns;
}

std::vector<ResultColumn> SelectResultColumns(const Scene& scene, const std::string& list,
                                              const std::string& option) {
  const std::vector<ResultColumn> all = AllResultColumns(scene);
  std::string allowed;
  for (const auto& column : all) allowed += (allowed.empty() ? "" : ", ") + column.name;
  std::vector<ResultColumn> chosen;
  std::vector<bool> taken(all.size(), false);
  size_t start = 0;
  for (int entry = 0;; ++entry) {
    const size_t comma = list.find(',', start);
    const std::string name =
        list.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const std::string at = "option " + option + ": ";
    if (name.empty()) {
      throw InputError(at + "empty column name in '" + list + "' (allowed: " + allowed + ")");
    }
    if (name == "time" && entry == 0) {
      // Always written first; naming it is allowed.
    } else {
      size_t c = 0;
      while (c < all.size() && all[c].name != name) ++c;
      if (c == all.size()) {
        throw InputError(at + "unknown column '" + name + "' (allowed: " +
                         (name == "time" ? "time only first; " : "") + allowed + ")");
      }
      if (taken[c]) throw InputError(at + "column '" + name + "' is named twice");
      taken[c] = true;
      chosen.push_back(all[c]);
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (chosen.empty()) {
    throw InputError("option " + option +
                     ": names no output column besides time (allowed: " + allowed + ")");
  }
  return chosen;
}

ResultCsvWriter::ResultCsvWriter(std::ostream* out, std::string name,
                                 std::vector<ResultColumn> columns, int every)
    : out_(*out), name_(std::move(name)), columns_(std::move(columns)), every_(every) {
  if (every_ < 1) throw InputError("option --every: must be >= 1");
  out_ << "time";
  for (const auto& column : columns_) out_ << "," << column.name;
  out_ << "\n";
}

void ResultCsvWriter::Write(const OutputSample& sample) {
  if (sample.index % every_ != 0) return;
  line_.clear();
  AppendNumber(sample.time_s, &line_);
  for (const auto& column : columns_) {
    const double* row = column.block == OutputBlock::kTorque  ? sample.link_torque_Nm
                        : column.block == OutputBlock::kSpeed ? sample.mass_speed_rad_per_s
                                                              : sample.link_twist_rad;
    line_ += ',';
    AppendNumber(row[column.index], &line_);
  }
  line_ += '\n';
  out_ << line_;
  if (!out_) throw InputError(name_ + ": write failed after " + std::to_string(rows_) + " rows");
  ++rows_;
}

long KeptRows(long samples, int every) { return samples <= 0 ? 0 : (samples - 1) / every + 1; }

double EstimatedCsvBytes(long rows, int columns) {
  return static_cast<double>(rows) * columns * kCsvBytesPerNumber;
}

std::string LargeOutputWarning(const std::string& path, double bytes) {
  if (!(bytes > kLargeOutputBytes)) return "";
  char size[32];
  std::snprintf(size, sizeof(size), "%.1f GB", bytes / 1e9);
  return "warning: " + path + " will take about " + size +
         "; --every N keeps every N-th sample, --columns chooses the outputs, --kd-only writes "
         "no CSV";
}

}  // namespace millkit::driveline
