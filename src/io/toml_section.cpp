#include "io/toml_section.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "millkit/io/input_error.h"
#include "millkit/io/input_file.h"

namespace millkit {

toml::table LoadTomlFile(const std::filesystem::path& path) {
  CheckInputFile(path);
  // Read here rather than by toml::parse_file, which needs a file it can seek: a pipe
  // (millkit simulate <(...)) is read as a CSV input is.
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open file");
  std::ostringstream text;
  text << in.rdbuf();
  try {
    return toml::parse(text.str(), path.string());
  } catch (const toml::parse_error& error) {
    const auto& where = error.source().begin;
    throw InputError(path.string() + ":" + std::to_string(where.line) + ":" +
                     std::to_string(where.column) +
                     ": TOML syntax: " + std::string(error.description()));
  }
}

TomlSection::TomlSection(const toml::table& table, std::string file, std::string where)
    : table_(&table), file_(std::move(file)), where_(std::move(where)) {}

std::string TomlSection::KeyContext(std::string_view key) const {
  std::string context = file_ + ": ";
  if (!where_.empty()) context += where_ + " ";
  context += "key '" + std::string(key) + "'";
  if (const auto* node = table_->get(key)) {
    const auto line = node->source().begin.line;
    if (line > 0) context += " (line " + std::to_string(line) + ")";
  }
  return context;
}

void TomlSection::Fail(std::string_view key, const std::string& rule) const {
  throw InputError(KeyContext(key) + ": " + rule);
}

void TomlSection::RequireOnlyKeys(std::initializer_list<std::string_view> allowed) const {
  for (const auto& [key, node] : *table_) {
    bool known = false;
    for (const auto& a : allowed) known = known || key.str() == a;
    if (!known) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
      Fail(key.str(), "unknown key (allowed here: " + list + ")");
    }
  }
}

std::optional<double> TomlSection::OptionalNumber(std::string_view key) const {
  const auto* node = table_->get(key);
  if (node == nullptr) return std::nullopt;
  double value = 0.0;
  if (const auto* f = node->as_floating_point()) {
    value = f->get();
  } else if (const auto* i = node->as_integer()) {
    value = static_cast<double>(i->get());
  } else {
    Fail(key, "must be a number");
  }
  if (!std::isfinite(value)) Fail(key, "must be a finite number");
  return value;
}

double TomlSection::RequiredNumber(std::string_view key) const {
  const auto value = OptionalNumber(key);
  if (!value) Fail(key, "is required");
  return *value;
}

double TomlSection::Number(std::string_view key, double fallback) const {
  return OptionalNumber(key).value_or(fallback);
}

std::optional<std::string> TomlSection::OptionalString(std::string_view key) const {
  const auto* node = table_->get(key);
  if (node == nullptr) return std::nullopt;
  const auto* s = node->as_string();
  if (s == nullptr) Fail(key, "must be a string");
  return s->get();
}

std::string TomlSection::RequiredString(std::string_view key) const {
  const auto value = OptionalString(key);
  if (!value) Fail(key, "is required");
  return *value;
}

std::string TomlSection::String(std::string_view key, const std::string& fallback) const {
  return OptionalString(key).value_or(fallback);
}

bool TomlSection::Bool(std::string_view key, bool fallback) const {
  const auto* node = table_->get(key);
  if (node == nullptr) return fallback;
  const auto* b = node->as_boolean();
  if (b == nullptr) Fail(key, "must be true or false");
  return b->get();
}

std::vector<std::string> TomlSection::RequiredStringArray(std::string_view key) const {
  const auto* node = table_->get(key);
  if (node == nullptr) Fail(key, "is required");
  const auto* array = node->as_array();
  if (array == nullptr) Fail(key, "must be an array of strings");
  std::vector<std::string> values;
  for (const auto& element : *array) {
    const auto* s = element.as_string();
    if (s == nullptr) Fail(key, "must be an array of strings");
    values.push_back(s->get());
  }
  return values;
}

std::vector<double> TomlSection::NumberArray(std::string_view key) const {
  std::vector<double> values;
  const auto* node = table_->get(key);
  if (node == nullptr) return values;
  const auto* array = node->as_array();
  if (array == nullptr) Fail(key, "must be an array of numbers");
  for (const auto& element : *array) {
    if (const auto* f = element.as_floating_point()) {
      values.push_back(f->get());
    } else if (const auto* i = element.as_integer()) {
      values.push_back(static_cast<double>(i->get()));
    } else {
      Fail(key, "must be an array of numbers");
    }
    if (!std::isfinite(values.back())) Fail(key, "must hold finite numbers");
  }
  return values;
}

std::optional<TomlSection> TomlSection::OptionalTable(std::string_view key) const {
  const auto* node = table_->get(key);
  if (node == nullptr) return std::nullopt;
  const auto* table = node->as_table();
  if (table == nullptr) Fail(key, "must be a table [" + std::string(key) + "]");
  return TomlSection(*table, file_, "[" + std::string(key) + "]");
}

std::vector<TomlSection> TomlSection::TableArray(std::string_view key) const {
  std::vector<TomlSection> sections;
  const auto* node = table_->get(key);
  if (node == nullptr) return sections;
  const auto* array = node->as_array();
  if (array == nullptr || !array->is_array_of_tables()) {
    Fail(key, "must be an array of tables [[" + std::string(key) + "]]");
  }
  int index = 0;
  for (const auto& element : *array) {
    ++index;
    sections.emplace_back(*element.as_table(), file_,
                          "[[" + std::string(key) + "]] #" + std::to_string(index));
  }
  return sections;
}

double TomlSection::Positive(std::string_view key, double value) const {
  if (!(value > 0.0)) Fail(key, "must be > 0 (got " + FormatNumber(value) + ")");
  return value;
}

double TomlSection::NonNegative(std::string_view key, double value) const {
  if (!(value >= 0.0)) Fail(key, "must be >= 0 (got " + FormatNumber(value) + ")");
  return value;
}

double TomlSection::InRange(std::string_view key, double value, double low, double high) const {
  if (!(value >= low && value <= high)) {
    Fail(key, "must lie in [" + FormatNumber(low) + ", " + FormatNumber(high) + "] (got " +
                  FormatNumber(value) + ")");
  }
  return value;
}

long TomlSection::Integer(std::string_view key, long fallback, long low, long high) const {
  const double value = Number(key, static_cast<double>(fallback));
  if (!(value == std::floor(value) && value >= static_cast<double>(low) &&
        value <= static_cast<double>(high))) {
    // Appended piece by piece: GCC 12 reports a false -Wrestrict on literal + std::string.
    std::string rule = "must be a whole number in [";
    rule += std::to_string(low);
    rule += ", ";
    rule += std::to_string(high);
    rule += "] (got ";
    rule += FormatNumber(value);
    rule += ")";
    Fail(key, rule);
  }
  return static_cast<long>(value);
}

}  // namespace millkit
