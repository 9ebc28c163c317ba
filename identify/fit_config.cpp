#include "millkit/identify/fit_config.h"

#include <algorithm>
#include <cmath>

#include "io/toml_section.h"
#include "millkit/io/input_error.h"

namespace millkit::identify {
namespace {

using driveline::SceneParameter;

constexpr double kDefaultBiteHalfRange_s = 0.02;

std::string Describe(const FreeParameter& p) {
  return "[" + FormatNumber(p.lower) + ", " + FormatNumber(p.upper) + "]";
}

// Bounds must be ordered, inside the physical range, and hold the start.
void CheckFreeParameter(const FreeParameter& p, const std::string& where) {
  if (!(std::isfinite(p.lower) && std::isfinite(p.upper) && std::isfinite(p.start))) {
    throw InputError(where + ": '" + p.parameter.name + "': start and bounds must be finite");
  }
  if (!(p.lower < p.upper)) {
    throw InputError(where + ": '" + p.parameter.name + "': lower bound " + FormatNumber(p.lower) +
                     " must be below upper bound " + FormatNumber(p.upper));
  }
  if (p.start < p.lower || p.start > p.upper) {
    throw InputError(where + ": '" + p.parameter.name + "': start " + FormatNumber(p.start) +
                     " lies outside its bounds " + Describe(p));
  }
  const auto range = driveline::PhysicalRange(p.parameter.kind);
  const bool below = range.lower_inclusive ? p.lower < range.lower : p.lower <= range.lower;
  if (below || p.upper > range.upper) {
    throw InputError(where + ": '" + p.parameter.name + "': bounds " + Describe(p) +
                     " leave the physical range of " + p.parameter.name + " (" +
                     (range.lower_inclusive ? ">= " : "> ") + FormatNumber(range.lower) +
                     (std::isfinite(range.upper) ? ", <= " + FormatNumber(range.upper) : "") + ")");
  }
}

// Each record is its own bite: its load starts at its own time on its recorder's clock.
bool PerRecordByDefault(SceneParameter::Kind kind) {
  return kind == SceneParameter::Kind::kBiteTime;
}

// The time span every record covers (an empty span when they do not overlap: the window check
// then names the record).
std::pair<double, double> CommonSpan(const std::vector<Oscillogram>& records) {
  double first = records.front().time_s.front();
  double last = records.front().time_s.back();
  for (const auto& record : records) {
    first = std::max(first, record.time_s.front());
    last = std::min(last, record.time_s.back());
  }
  return {first, last};
}

// Every parameter can hold a fit in a wrong basin (a damping too: a wrong one changes which
// impacts happen), so the scan covers them all unless the config says otherwise.
bool ScannedByDefault(SceneParameter::Kind) { return true; }

// The channel's unit from the records' units rows, checked against the config's (when given):
// every record must agree.
TorqueUnit ChannelUnit(const std::string& column, const std::optional<TorqueUnit>& configured,
                       const std::vector<Oscillogram>& records, const std::string& where) {
  std::optional<TorqueUnit> unit = configured;
  std::string unit_source = where;
  for (const auto& record : records) {
    const int j = record.ChannelIndex(column);
    if (j < 0 || j >= static_cast<int>(record.units.size()) || record.units[j].empty()) continue;
    const std::string row_where = record.source + ", units row of column '" + column + "'";
    const auto row_unit = ParseTorqueUnit(record.units[j]);
    // The config's unit stands for a recorder's unit that is not a torque's (V after a
    // calibration the recorder does not know); two torque units must agree.
    if (!row_unit && configured) continue;
    if (!row_unit) {
      throw InputError(row_where + ": '" + record.units[j] +
                       "' is not a torque unit; a channel takes N*m, kN*m or MN*m (when its "
                       "values are torques, give the unit in its [[channel]])");
    }
    if (unit && unit->name != row_unit->name) {
      throw InputError(row_where + " says " + row_unit->name + ", " + unit_source + " says " +
                       unit->name + "; make them agree");
    }
    unit = row_unit;
    unit_source = row_where;
  }
  return unit ? *unit : TorqueUnit{"N*m", 1.0};
}

}  // namespace

std::optional<TorqueUnit> ParseTorqueUnit(const std::string& text) {
  std::string key;
  for (size_t k = 0; k < text.size(); ++k) {
    const char c = text[k];
    if (text.compare(k, 2, "\xC2\xB7") == 0) {  // U+00B7 middle dot
      ++k;
      continue;
    }
    if (c == ' ' || c == '*' || c == '.' || c == '[' || c == ']' || c == '(' || c == ')') continue;
    key += c;
  }
  if (key == "Nm") return TorqueUnit{"N*m", 1.0};
  if (key == "kNm") return TorqueUnit{"kN*m", 1e3};
  if (key == "MNm") return TorqueUnit{"MN*m", 1e6};
  return std::nullopt;
}

void ValidateFitConfig(const FitConfig& config, const std::vector<Oscillogram>& records,
                       const std::string& where) {
  if (records.empty()) throw InputError(where + ": no record to fit");
  if (config.free.empty()) throw InputError(where + ": no free parameter to fit");
  if (config.channels.empty()) throw InputError(where + ": no channel to fit");
  for (size_t i = 0; i < config.free.size(); ++i) {
    CheckFreeParameter(config.free[i], where);
    for (size_t j = 0; j < i; ++j) {
      if (config.free[j].parameter.name == config.free[i].parameter.name) {
        throw InputError(where + ": parameter '" + config.free[i].parameter.name +
                         "' is listed twice");
      }
    }
  }
  for (size_t i = 0; i < config.channels.size(); ++i) {
    const auto& c = config.channels[i];
    for (const auto& record : records) {
      if (record.ChannelIndex(c.column) < 0) {
        throw InputError(where + ": channel '" + c.column + "' is missing from the record " +
                         record.source);
      }
    }
    if (c.link_index < 0) throw InputError(where + ": channel '" + c.column + "': no such link");
    if (!(c.gain_lower > 0.0 && c.gain_lower <= 1.0 && c.gain_upper >= 1.0 &&
          std::isfinite(c.gain_upper))) {
      throw InputError(where + ": channel '" + c.column +
                       "': gain bounds must satisfy 0 < lower <= 1 <= upper");
    }
    if (c.offset_limit_Nm && !(*c.offset_limit_Nm > 0.0 && std::isfinite(*c.offset_limit_Nm))) {
      throw InputError(where + ": channel '" + c.column + "': offset_limit must be > 0");
    }
    if (c.weight && !(*c.weight > 0.0 && std::isfinite(*c.weight))) {
      throw InputError(where + ": channel '" + c.column + "': weight must be > 0");
    }
    for (size_t j = 0; j < i; ++j) {
      if (config.channels[j].column == c.column) {
        throw InputError(where + ": channel '" + c.column + "' is listed twice");
      }
    }
  }
  for (const auto& record : records) {
    const double first = record.time_s.front();
    const double last = record.time_s.back();
    if (!(config.window_start_s < config.window_end_s) || config.window_start_s < first ||
        config.window_end_s > last) {
      throw InputError(where + ": window [" + FormatNumber(config.window_start_s) + ", " +
                       FormatNumber(config.window_end_s) + "] s must be an interval inside the " +
                       "record's time span [" + FormatNumber(first) + ", " + FormatNumber(last) +
                       "] s of " + record.source);
    }
    const auto [begin, end] = record.WindowRange(config.window_start_s, config.window_end_s);
    if (end - begin < kMinRecordSamples) {
      throw InputError(where + ": window holds " + std::to_string(end - begin) + " samples of " +
                       record.source + "; a fit needs at least " +
                       std::to_string(kMinRecordSamples));
    }
  }
  if (config.time_origin_s) {
    for (const auto& record : records) {
      if (!(std::isfinite(*config.time_origin_s) &&
            *config.time_origin_s <= record.time_s.front())) {
        throw InputError(where + ": time_origin " + FormatNumber(*config.time_origin_s) +
                         " s must be finite and not after the first sample (" +
                         FormatNumber(record.time_s.front()) + " s) of " + record.source);
      }
    }
  }
  if (config.scan_points < 0) throw InputError(where + ": scan must be >= 0");
  if (config.starts < 1) throw InputError(where + ": starts must be >= 1");
}

FitConfig LoadFitConfig(const std::string& path, const Oscillogram& record,
                        const driveline::Scene& scene) {
  return LoadFitConfig(path, std::vector<Oscillogram>{record}, scene);
}

void ApplySetValues(const FitConfig& config, driveline::Scene* scene) {
  for (const auto& [parameter, value] : config.set) parameter.Set(value, scene);
  if (!config.set.empty()) driveline::ValidateScene(*scene);
}

FitConfig LoadFitConfig(const std::string& path, const std::vector<Oscillogram>& records,
                        const driveline::Scene& given_scene) {
  if (records.empty()) throw InputError(path + ": no record to fit");
  // The [set] values are checked, and the defaults of the [[free]] starts read, on a copy with
  // them applied; the caller applies them to its own scene (ApplySetValues).
  driveline::Scene with_set = given_scene;
  driveline::Scene* scene = &with_set;
  const toml::table root = LoadTomlFile(path);
  const TomlSection top(root, path, "");
  top.RequireOnlyKeys({"fit", "set", "free", "channel"});
  FitConfig config;
  const auto [span_first, span_last] = CommonSpan(records);
  config.window_start_s = span_first;
  config.window_end_s = span_last;
  if (const auto fit = top.OptionalTable("fit")) {
    fit->RequireOnlyKeys({"window", "scan", "starts", "seed", "time_origin", "derivatives"});
    if (fit->Has("time_origin")) config.time_origin_s = fit->RequiredNumber("time_origin");
    if (fit->Has("window")) {
      const auto window = fit->NumberArray("window");
      if (window.size() != 2) fit->Fail("window", "must be [start, end] in s");
      config.window_start_s = window[0];
      config.window_end_s = window[1];
      for (const auto& record : records) {
        if (!(window[0] < window[1]) || window[0] < record.time_s.front() ||
            window[1] > record.time_s.back()) {
          fit->Fail("window", "must be an interval inside the record's time span [" +
                                  FormatNumber(record.time_s.front()) + ", " +
                                  FormatNumber(record.time_s.back()) + "] s of " + record.source);
        }
      }
    }
    config.scan_points = static_cast<int>(fit->Integer("scan", kDefaultScanPoints, 0, 100000));
    config.starts = static_cast<int>(fit->Integer("starts", kDefaultStarts, 1, 10000));
    config.seed = static_cast<unsigned>(fit->Integer("seed", 1, 0, 4294967295L));
    if (const auto derivatives = fit->OptionalString("derivatives")) {
      Derivatives kind;
      if (!ParseDerivatives(*derivatives, &kind)) {
        fit->Fail("derivatives", "must be \"sensitivity\", \"forward\" or \"central\" (got \"" +
                                     *derivatives + "\")");
      }
      config.derivatives = kind;
    }
  }
  if (const auto set = top.OptionalTable("set")) {
    for (const auto& [key, node] : set->table()) {
      const std::string name(key.str());
      const auto parameter = driveline::ParseSceneParameter(*scene, name, set->KeyContext(name));
      const double value = *set->OptionalNumber(name);
      const auto range = driveline::PhysicalRange(parameter.kind);
      if (value < range.lower || value > range.upper ||
          (!range.lower_inclusive && value == range.lower)) {
        set->Fail(name,
                  "value " + FormatNumber(value) + " is outside the physical range of " + name);
      }
      parameter.Set(value, scene);
      config.set.emplace_back(parameter, value);
    }
    driveline::ValidateScene(*scene);
  }
  int index = 0;
  for (const auto& section : top.TableArray("free")) {
    ++index;
    section.RequireOnlyKeys({"name", "start", "lower", "upper", "scan", "per_record"});
    FreeParameter p;
    p.parameter = driveline::ParseSceneParameter(*scene, section.RequiredString("name"),
                                                 section.KeyContext("name"));
    p.start = section.Number("start", p.parameter.Get(*scene));
    p.lower = section.RequiredNumber("lower");
    p.upper = section.RequiredNumber("upper");
    p.scan = section.Bool("scan", ScannedByDefault(p.parameter.kind));
    p.per_record = section.Bool("per_record", PerRecordByDefault(p.parameter.kind));
    CheckFreeParameter(p, path + ": [[free]] #" + std::to_string(index));
    config.free.push_back(p);
  }
  index = 0;
  for (const auto& section : top.TableArray("channel")) {
    ++index;
    section.RequireOnlyKeys({"column", "link", "unit", "weight", "gain", "offset", "lowpass",
                             "gain_bounds", "offset_limit"});
    ChannelSpec c;
    c.column = section.RequiredString("column");
    for (const auto& record : records) {
      if (record.ChannelIndex(c.column) < 0) {
        section.Fail("column", "no column '" + c.column + "' in the record " + record.source);
      }
    }
    c.link = section.String("link", c.column);
    c.link_index = scene->LinkIndex(c.link);
    if (c.link_index < 0) section.Fail("link", "no link named '" + c.link + "' in the scene");
    std::optional<TorqueUnit> configured_unit;
    if (section.Has("unit")) {
      configured_unit = ParseTorqueUnit(section.RequiredString("unit"));
      if (!configured_unit) section.Fail("unit", "must be \"N*m\", \"kN*m\" or \"MN*m\"");
    }
    c.unit = ChannelUnit(c.column, configured_unit, records, section.KeyContext("unit"));
    // weight and offset_limit are given in the channel's unit, kept in N·m.
    if (section.Has("weight")) {
      c.weight =
          section.Positive("weight", section.RequiredNumber("weight")) / c.unit.newton_metres;
    }
    c.fit_gain = section.Bool("gain", true);
    c.fit_offset = section.Bool("offset", true);
    c.lowpass_Hz = section.NonNegative("lowpass", section.Number("lowpass", 0.0));
    if (section.Has("gain_bounds")) {
      const auto bounds = section.NumberArray("gain_bounds");
      if (bounds.size() != 2 ||
          !(bounds[0] > 0.0 && bounds[0] <= 1.0 && bounds[1] >= 1.0 && std::isfinite(bounds[1]))) {
        section.Fail("gain_bounds", "must be [lower, upper] with 0 < lower <= 1 <= upper");
      }
      c.gain_lower = bounds[0];
      c.gain_upper = bounds[1];
    }
    if (section.Has("offset_limit")) {
      c.offset_limit_Nm = section.Positive("offset_limit", section.RequiredNumber("offset_limit")) *
                          c.unit.newton_metres;
    }
    config.channels.push_back(c);
  }
  ValidateFitConfig(config, records, path);
  return config;
}

FitConfig DefaultFitConfig(const driveline::Scene& scene, const Oscillogram& record) {
  return DefaultFitConfig(scene, std::vector<Oscillogram>{record});
}

FitConfig DefaultFitConfig(const driveline::Scene& scene, const std::vector<Oscillogram>& records) {
  if (records.empty()) throw InputError("default fit of " + scene.file + ": no record to fit");
  const Oscillogram& record = records.front();
  FitConfig config;
  std::tie(config.window_start_s, config.window_end_s) = CommonSpan(records);
  for (size_t j = 0; j < record.channels.size(); ++j) {
    const int link = scene.LinkIndex(record.channels[j]);
    if (link < 0) continue;
    ChannelSpec c;
    c.column = c.link = record.channels[j];
    c.link_index = link;
    c.unit = ChannelUnit(c.column, std::nullopt, records, "default fit of " + scene.file);
    config.channels.push_back(c);
  }
  if (config.channels.empty()) {
    throw InputError(record.source + ": no column is named like a link of scene " + scene.file +
                     "; give a fit config with [[channel]] tables");
  }
  const std::string where = "default fit of " + scene.file;
  // scan and per_record follow the rules a [[free]] table gets by default.
  const auto add = [&](const std::string& name, double start, double lower, double upper) {
    FreeParameter p;
    p.parameter = driveline::ParseSceneParameter(scene, name, where);
    p.start = start;
    p.lower = lower;
    p.upper = upper;
    p.scan = ScannedByDefault(p.parameter.kind);
    p.per_record = PerRecordByDefault(p.parameter.kind);
    config.free.push_back(p);
  };
  for (const auto& link : scene.links) {
    const double d = link.damping_Nms_per_rad;
    const double b = link.backlash_rad;
    if (d > 0.0) add(link.name + ".damping", d, d / 10.0, d * 10.0);
    if (b > 0.0) add(link.name + ".backlash", b, b / 5.0, b * 3.0);
  }
  if (!scene.torques.empty()) {
    const double bite = driveline::ParseSceneParameter(scene, "bite_time", where).Get(scene);
    add("bite_time", bite, std::max(0.0, bite - kDefaultBiteHalfRange_s),
        bite + kDefaultBiteHalfRange_s);
  }
  ValidateFitConfig(config, records, where);
  return config;
}

}  // namespace millkit::identify
