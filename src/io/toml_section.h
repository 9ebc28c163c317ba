// Reading validated values from TOML files. Every error names the file, the table and the key,
// and the rule that was broken, e.g. "scene.toml: [[link]] #2 'upper_spindle': key 'stiffness':
// must be > 0 (got -5)".
#pragma once

#include <toml++/toml.h>

#include <filesystem>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "millkit/io/number_format.h"

namespace millkit {

// Parses a TOML file; a syntax error is an InputError naming file, line and column.
toml::table LoadTomlFile(const std::filesystem::path& path);

// A view of one TOML table with the context needed for error messages.
class TomlSection {
 public:
  TomlSection(const toml::table& table, std::string file, std::string where);

  const toml::table& table() const { return *table_; }
  const std::string& file() const { return file_; }
  bool Has(std::string_view key) const { return table_->contains(key); }

  // Throws when the table has a key outside `allowed`.
  void RequireOnlyKeys(std::initializer_list<std::string_view> allowed) const;

  double RequiredNumber(std::string_view key) const;
  double Number(std::string_view key, double fallback) const;
  std::optional<double> OptionalNumber(std::string_view key) const;
  std::string RequiredString(std::string_view key) const;
  std::string String(std::string_view key, const std::string& fallback) const;
  std::optional<std::string> OptionalString(std::string_view key) const;
  std::vector<std::string> RequiredStringArray(std::string_view key) const;
  std::vector<double> NumberArray(std::string_view key) const;
  bool Bool(std::string_view key, bool fallback) const;
  // A sub-table (optional): nullopt when the key is absent; error when it is not a table.
  std::optional<TomlSection> OptionalTable(std::string_view key) const;
  // An array of tables ([[key]]); empty when absent.
  std::vector<TomlSection> TableArray(std::string_view key) const;

  // "file: [where] key 'k'" for messages about a key of this table.
  std::string KeyContext(std::string_view key) const;
  // Throws InputError "<KeyContext(key)>: <rule>".
  [[noreturn]] void Fail(std::string_view key, const std::string& rule) const;

  // Range checks that throw with the rule named; each returns its value for chaining.
  double Positive(std::string_view key, double value) const;
  double NonNegative(std::string_view key, double value) const;
  double InRange(std::string_view key, double value, double low, double high) const;
  // An optional whole number in [low, high], checked before any conversion (a value such as 3e9
  // or 2.5 is an error naming the rule, never a wrapped or truncated integer).
  long Integer(std::string_view key, long fallback, long low, long high) const;

 private:
  const toml::table* table_;
  std::string file_;
  std::string where_;
};

}  // namespace millkit
