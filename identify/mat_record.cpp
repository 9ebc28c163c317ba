#include "millkit/identify/mat_record.h"

#include <matio.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "identify/mat_prescan.h"
#include "millkit/io/input_error.h"

namespace millkit::identify {
namespace {

struct VariableDeleter {
  void operator()(matvar_t* variable) const { Mat_VarFree(variable); }
};
using Variable = std::unique_ptr<matvar_t, VariableDeleter>;

struct FileCloser {
  void operator()(mat_t* file) const { Mat_Close(file); }
};

// libmatio reports malformed files through its log; the reader's own message names the file.
void QuietLog(int /*level*/, char* /*message*/) {}

// A variable or struct field in the scope the record is read from.
struct Entry {
  std::string name;
  matvar_t* variable = nullptr;
};

size_t Elements(const matvar_t& v) {
  size_t n = 1;
  for (int d = 0; d < v.rank; ++d) n *= v.dims[d];
  return n;
}

std::string Shape(const matvar_t& v) {
  std::string shape;
  for (int d = 0; d < v.rank; ++d) {
    if (d > 0) shape += 'x';
    shape += std::to_string(v.dims[d]);
  }
  return shape;
}

template <typename T>
void Widen(const void* data, size_t n, std::vector<double>* values) {
  const T* typed = static_cast<const T*>(data);
  values->assign(typed, typed + n);
}

// The elements of a real numeric vector as doubles; otherwise an empty string with the values,
// or why it is not one.
std::string NumericVector(const matvar_t& v, std::vector<double>* values) {
  if (v.class_type == MAT_C_STRUCT) return "a struct";
  if (v.class_type == MAT_C_CELL) return "a cell array";
  if (v.class_type == MAT_C_CHAR) return "text";
  if (v.class_type == MAT_C_SPARSE) return "a sparse matrix";
  if (v.isComplex) return "complex";
  if (v.rank != 2 || (v.dims[0] != 1 && v.dims[1] != 1)) return "not a vector (" + Shape(v) + ")";
  const size_t n = Elements(v);
  if (n > 0 && v.data == nullptr) return "unreadable";
  switch (v.data_type) {
    case MAT_T_DOUBLE:
      Widen<double>(v.data, n, values);
      break;
    case MAT_T_SINGLE:
      Widen<float>(v.data, n, values);
      break;
    case MAT_T_INT8:
      Widen<std::int8_t>(v.data, n, values);
      break;
    case MAT_T_UINT8:
      Widen<std::uint8_t>(v.data, n, values);
      break;
    case MAT_T_INT16:
      Widen<std::int16_t>(v.data, n, values);
      break;
    case MAT_T_UINT16:
      Widen<std::uint16_t>(v.data, n, values);
      break;
    case MAT_T_INT32:
      Widen<std::int32_t>(v.data, n, values);
      break;
    case MAT_T_UINT32:
      Widen<std::uint32_t>(v.data, n, values);
      break;
    case MAT_T_INT64:
      Widen<std::int64_t>(v.data, n, values);
      break;
    case MAT_T_UINT64:
      Widen<std::uint64_t>(v.data, n, values);
      break;
    default:
      return "not numeric";
  }
  return "";
}

std::vector<Entry> StructFields(matvar_t* s) {
  std::vector<Entry> fields;
  const unsigned count = Mat_VarGetNumberOfFields(s);
  char* const* names = Mat_VarGetStructFieldnames(s);
  for (unsigned f = 0; f < count && names != nullptr; ++f) {
    matvar_t* field = Mat_VarGetStructFieldByName(s, names[f], 0);
    if (field != nullptr) fields.push_back({names[f], field});
  }
  return fields;
}

}  // namespace

Oscillogram LoadMatRecord(const std::filesystem::path& path, const RecordOptions& options) {
  const std::string source = path.string();
  // libmatio trusts the sizes the file declares; MillKit checks them first.
  CheckMatFile(path, source);
  Mat_LogInitFunc("millkit", QuietLog);
  std::unique_ptr<mat_t, FileCloser> file(Mat_Open(source.c_str(), MAT_ACC_RDONLY));
  if (!file) {
    throw InputError(source + ": cannot open it as a MATLAB file (MAT v5 or v7.3 expected)");
  }
  std::vector<Variable> variables;
  while (matvar_t* v = Mat_VarReadNext(file.get())) variables.emplace_back(v);
  if (variables.empty()) throw InputError(source + ": holds no variable");

  const auto is_time = [&options](const std::string& name) {
    return options.time_column.empty() ? IsTimeColumnName(name) : name == options.time_column;
  };
  const std::string time_rule =
      options.time_column.empty()
          ? "named 'time', 't', 'Time' or 'time_s'"
          : "named '" + options.time_column + "' (RecordOptions::time_column)";
  // The scope: the top level when it holds the time vector, else the one struct that does.
  std::vector<Entry> scope;
  scope.reserve(variables.size());
  for (const auto& v : variables) scope.push_back({v->name ? v->name : "", v.get()});
  std::string prefix;
  bool top_has_time = false;
  for (const auto& e : scope) top_has_time = top_has_time || is_time(e.name);
  if (!top_has_time) {
    std::vector<Entry> holders;
    std::string seen;
    for (const auto& e : scope) {
      seen += (seen.empty() ? "" : ", ") + e.name + " (" + Shape(*e.variable) + ")";
      if (e.variable->class_type != MAT_C_STRUCT || Elements(*e.variable) != 1) continue;
      for (const auto& field : StructFields(e.variable)) {
        if (is_time(field.name)) {
          holders.push_back(e);
          break;
        }
      }
    }
    if (holders.empty()) {
      throw InputError(source + ": no time vector " + time_rule +
                       " at the top level or in a struct; seen: " + seen);
    }
    if (holders.size() > 1) {
      throw InputError(source + ": the structs '" + holders[0].name + "' and '" + holders[1].name +
                       "' both hold a time vector; save one record per file");
    }
    prefix = holders[0].name + ".";
    scope = StructFields(holders[0].variable);
  }

  Oscillogram record;
  record.source = source;
  int time_entry = -1;
  for (size_t i = 0; i < scope.size(); ++i) {
    if (!is_time(scope[i].name)) continue;
    if (time_entry >= 0) {
      throw InputError(source + ": two time vectors, '" + prefix + scope[time_entry].name +
                       "' and '" + prefix + scope[i].name +
                       "'; choose one with RecordOptions::time_column");
    }
    time_entry = static_cast<int>(i);
    const std::string why = NumericVector(*scope[i].variable, &record.time_s);
    if (!why.empty()) {
      throw InputError(source + ": time '" + prefix + scope[i].name + "' is " + why +
                       "; it must be a real numeric vector");
    }
  }
  const std::string time_name = prefix + scope[time_entry].name;
  const size_t n = record.time_s.size();
  if (n < static_cast<size_t>(kMinRecordSamples)) {
    throw InputError(source + ": " + std::to_string(n) + " samples in '" + time_name +
                     "'; a record needs at least " + std::to_string(kMinRecordSamples));
  }
  const auto require_finite = [&source](const std::string& name, const std::vector<double>& v) {
    for (size_t k = 0; k < v.size(); ++k) {
      if (!std::isfinite(v[k])) {
        throw InputError(source + ": " + name + "(" + std::to_string(k + 1) +
                         ") is not a finite number");
      }
    }
  };
  require_finite(time_name, record.time_s);
  for (size_t k = 1; k < n; ++k) {
    if (!(record.time_s[k] > record.time_s[k - 1])) {
      throw InputError(source + ": " + time_name + "(" + std::to_string(k + 1) +
                       "): time must increase strictly");
    }
  }
  for (size_t i = 0; i < scope.size(); ++i) {
    if (static_cast<int>(i) == time_entry) continue;
    std::vector<double> values;
    std::string why = NumericVector(*scope[i].variable, &values);
    if (why.empty() && values.size() != n) {
      why = std::to_string(values.size()) + " samples, the time has " + std::to_string(n);
    }
    if (!why.empty()) {
      record.notes.push_back(source + ": '" + prefix + scope[i].name + "' is not a channel (" +
                             why + "), skipped");
      continue;
    }
    require_finite(prefix + scope[i].name, values);
    record.channels.push_back(scope[i].name);
    record.units.emplace_back();
    record.values.push_back(std::move(values));
  }
  if (record.channels.empty()) {
    throw InputError(source + ": no channel: no other real vector of " + std::to_string(n) +
                     " samples beside the time '" + time_name + "'");
  }
  record.line_numbers.resize(n);
  for (size_t k = 0; k < n; ++k) record.line_numbers[k] = static_cast<int>(k + 1);
  return record;
}

}  // namespace millkit::identify
