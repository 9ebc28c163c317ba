#include "millkit/identify/comtrade.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "millkit/io/input_error.h"
#include "millkit/io/input_file.h"

namespace millkit::identify {
namespace {

std::string Trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

std::vector<std::string> Fields(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) fields.push_back(Trim(field));
  // A line of blanks trims to "" (back() on it was undefined; found by tests/fuzz/comtrade_fuzz).
  const std::string trimmed = Trim(line);
  if (!trimmed.empty() && trimmed.back() == ',') fields.push_back("");
  return fields;
}

// Reads .cfg lines with their numbers, for messages.
class CfgReader {
 public:
  explicit CfgReader(const std::filesystem::path& path) : path_(path.string()) {
    CheckInputFile(path);
    std::ifstream in(path);
    if (!in) throw InputError(path_ + ": cannot open file");
    std::string line;
    while (std::getline(in, line)) {
      if (lines_.empty() && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
      lines_.push_back(line);
    }
  }
  std::vector<std::string> Next(const std::string& what) {
    if (next_ >= lines_.size()) {
      throw InputError(path_ + ": ends before the " + what + " line");
    }
    return Fields(lines_[next_++]);
  }
  bool HasMore() const { return next_ < lines_.size(); }
  std::string Where() const { return path_ + ": line " + std::to_string(next_); }
  // A count or sample number: a Number in int range (a cast from beyond it is undefined; found
  // by tests/fuzz/comtrade_fuzz).
  long Count(const std::string& text, const std::string& what) const {
    const double value = Number(text, what);
    if (!(std::abs(value) <= 2147483647.0)) {
      throw InputError(Where() + ": " + what + " '" + text + "' is out of range");
    }
    return static_cast<long>(value);
  }

  double Number(const std::string& text, const std::string& what) const {
    try {
      size_t used = 0;
      const double value = std::stod(text, &used);
      if (used != text.size() || !std::isfinite(value)) throw std::invalid_argument(text);
      return value;
    } catch (const std::exception&) {
      throw InputError(Where() + ": " + what + " '" + text + "' is not a number");
    }
  }

 private:
  std::string path_;
  std::vector<std::string> lines_;
  size_t next_ = 0;
};

struct Analog {
  std::string id;
  std::string unit;  // the .cfg's uu field
  double a = 1.0;
  double b = 0.0;
};

}  // namespace

Oscillogram LoadComtrade(const std::filesystem::path& cfg_path) {
  CfgReader cfg(cfg_path);
  cfg.Next("station");
  const auto counts = cfg.Next("channel count");
  if (counts.size() < 3) throw InputError(cfg.Where() + ": expected TT,##A,##D");
  const int total = static_cast<int>(cfg.Count(counts[0], "channel count"));
  const auto count_of = [&](const std::string& field, char kind) {
    if (field.empty() || std::toupper(static_cast<unsigned char>(field.back())) != kind) {
      throw InputError(cfg.Where() + ": '" + field + "' must end in " + kind);
    }
    return static_cast<int>(cfg.Count(field.substr(0, field.size() - 1), "channel count"));
  };
  const int analog_count = count_of(counts[1], 'A');
  const int digital_count = count_of(counts[2], 'D');
  if (analog_count + digital_count != total || analog_count < 1) {
    throw InputError(cfg.Where() + ": " + std::to_string(analog_count) + " analog + " +
                     std::to_string(digital_count) + " digital channels do not make " +
                     std::to_string(total) + ", or there is no analog channel");
  }
  std::vector<Analog> analogs;
  for (int k = 0; k < analog_count; ++k) {
    const auto f = cfg.Next("analog channel");
    if (f.size() < 7)
      throw InputError(cfg.Where() + ": an analog channel line needs at least 7 fields");
    Analog channel;
    channel.id = f[1];
    channel.unit = f[4];
    channel.a = cfg.Number(f[5], "multiplier a");
    channel.b = cfg.Number(f[6], "offset b");
    if (channel.id.empty()) throw InputError(cfg.Where() + ": analog channel without an id");
    analogs.push_back(channel);
  }
  for (int k = 0; k < digital_count; ++k) cfg.Next("digital channel");
  cfg.Next("line frequency");
  // An empty line has no field: .at(0) threw std::out_of_range (tests/fuzz/comtrade_fuzz).
  const auto rate_count = cfg.Next("sample rate count");
  if (rate_count.empty()) throw InputError(cfg.Where() + ": expected nrates");
  const int rates = static_cast<int>(cfg.Count(rate_count[0], "nrates"));
  std::vector<std::pair<double, long>> segments;  // (samples per s, last sample number)
  for (int k = 0; k < rates; ++k) {
    const auto f = cfg.Next("sample rate");
    if (f.size() < 2) throw InputError(cfg.Where() + ": expected samp,endsamp");
    segments.emplace_back(cfg.Number(f[0], "samp"), cfg.Count(f[1], "endsamp"));
  }
  cfg.Next("first sample time");
  cfg.Next("trigger time");
  const auto type_fields = cfg.Next("file type");
  std::string type = type_fields.empty() ? "" : type_fields[0];
  std::transform(type.begin(), type.end(), type.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  double time_multiplier = 1.0;
  if (cfg.HasMore()) {
    const auto f = cfg.Next("timemult");
    if (!f.empty() && !f[0].empty()) time_multiplier = cfg.Number(f[0], "timemult");
  }
  const bool from_rates =
      !segments.empty() &&
      std::all_of(segments.begin(), segments.end(), [](const auto& s) { return s.first > 0.0; });

  std::filesystem::path dat_path = cfg_path;
  dat_path.replace_extension(cfg_path.extension() == ".CFG" ? ".DAT" : ".dat");
  CheckInputFile(dat_path);
  std::ifstream dat(dat_path, std::ios::binary);
  if (!dat)
    throw InputError(dat_path.string() + ": cannot open the .dat file of " + cfg_path.string());
  Oscillogram record;
  record.source = cfg_path.string();
  for (const auto& a : analogs) {
    record.channels.push_back(a.id);
    record.units.push_back(a.unit);
  }
  record.values.assign(analogs.size(), {});
  std::vector<double> stamps;
  if (type == "ASCII") {
    std::string line;
    int line_number = 0;
    while (std::getline(dat, line)) {
      ++line_number;
      if (Trim(line).empty()) continue;
      const auto f = Fields(line);
      if (static_cast<int>(f.size()) < 2 + analog_count) {
        throw InputError(dat_path.string() + ": line " + std::to_string(line_number) + ": " +
                         std::to_string(f.size()) + " fields, expected " +
                         std::to_string(2 + total));
      }
      const auto number = [&](const std::string& text) {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || *end != '\0' || !std::isfinite(v)) {
          throw InputError(dat_path.string() + ": line " + std::to_string(line_number) + ": '" +
                           text + "' is not a number");
        }
        return v;
      };
      stamps.push_back(f[1].empty() ? NAN : number(f[1]));
      for (int c = 0; c < analog_count; ++c) {
        record.values[c].push_back(analogs[c].a * number(f[2 + c]) + analogs[c].b);
      }
      record.line_numbers.push_back(line_number);
    }
  } else if (type == "BINARY" || type == "BINARY32" || type == "FLOAT32") {
    const int width = type == "BINARY" ? 2 : 4;
    const int digital_words = (digital_count + 15) / 16;
    const size_t size =
        8 + static_cast<size_t>(analog_count) * width + 2 * static_cast<size_t>(digital_words);
    std::vector<unsigned char> sample(size);
    long index = 0;
    while (dat.read(reinterpret_cast<char*>(sample.data()), static_cast<std::streamsize>(size))) {
      const auto u32 = [&](size_t at) {
        return static_cast<std::uint32_t>(sample[at]) |
               static_cast<std::uint32_t>(sample[at + 1]) << 8 |
               static_cast<std::uint32_t>(sample[at + 2]) << 16 |
               static_cast<std::uint32_t>(sample[at + 3]) << 24;
      };
      stamps.push_back(static_cast<double>(u32(4)));
      for (int c = 0; c < analog_count; ++c) {
        const size_t at = 8 + static_cast<size_t>(c) * width;
        double x = 0.0;
        if (type == "BINARY") {
          x = static_cast<std::int16_t>(
              static_cast<std::uint16_t>(sample[at] | sample[at + 1] << 8));
        } else if (type == "BINARY32") {
          x = static_cast<std::int32_t>(u32(at));
        } else {
          const std::uint32_t bits = u32(at);
          float f = 0.0f;
          std::memcpy(&f, &bits, sizeof(f));
          x = f;
        }
        record.values[c].push_back(analogs[c].a * x + analogs[c].b);
      }
      record.line_numbers.push_back(static_cast<int>(++index));
    }
    if (dat.gcount() != 0) {
      throw InputError(dat_path.string() + ": ends inside sample " + std::to_string(index + 1) +
                       " (" + std::to_string(dat.gcount()) + " of " + std::to_string(size) +
                       " bytes): truncated");
    }
  } else {
    throw InputError(cfg_path.string() + ": file type '" + type +
                     "' is not ASCII, BINARY, BINARY32 or FLOAT32");
  }
  const size_t n = stamps.size();
  record.time_s.resize(n);
  if (from_rates) {
    // Within a segment t = t_start + (k − k_start)/samp: a division per sample, no accumulated
    // rounding (a single-rate record gets exactly k/samp).
    double segment_start_time = 0.0;
    size_t segment_start = 0;
    size_t segment = 0;
    for (size_t k = 0; k < n; ++k) {
      if (segment + 1 < segments.size() && static_cast<long>(k + 1) > segments[segment].second) {
        segment_start_time = record.time_s[k - 1] + 1.0 / segments[segment].first;
        segment_start = k;
        ++segment;
      }
      record.time_s[k] =
          segment_start_time + static_cast<double>(k - segment_start) / segments[segment].first;
    }
  } else {
    for (size_t k = 0; k < n; ++k) record.time_s[k] = stamps[k] * time_multiplier * 1e-6;
  }
  for (size_t k = 1; k < n; ++k) {
    if (!(record.time_s[k] > record.time_s[k - 1])) {
      throw InputError(dat_path.string() + ": sample " + std::to_string(k + 1) +
                       ": time does not increase strictly");
    }
  }
  if (static_cast<int>(n) < kMinRecordSamples) {
    throw InputError(dat_path.string() + ": " + std::to_string(n) +
                     " samples; a record needs at least " + std::to_string(kMinRecordSamples));
  }
  return record;
}

}  // namespace millkit::identify
