#include "millkit/leveller/leveller_config.h"

#include <cmath>
#include <numbers>

#include "io/toml_section.h"
#include "millkit/io/input_error.h"
#include "millkit/leveller/linkage.h"

namespace millkit::leveller {
namespace {

// Grid over the working range used to prove that the linkage assembles everywhere in it.
constexpr int kAssemblyGridPoints = 73;

std::string Describe(const char* name, double value) {
  return std::string(name) + " = " + FormatNumber(value) + " mm";
}

}  // namespace

std::optional<LinkageDefect> FindLinkageDefect(const LinkageGeometry& geo) {
  const std::pair<const char*, double> lengths[] = {
      {"ak_mm", geo.ak_mm}, {"bj_mm", geo.bj_mm}, {"hk_mm", geo.hk_mm},
      {"gj_mm", geo.gj_mm}, {"cg_mm", geo.cg_mm}, {"roll_diameter_mm", geo.roll_diameter_mm}};
  for (const auto& [key, value] : lengths) {
    if (!(value > 0.0)) return LinkageDefect{key, "must be > 0 (got " + FormatNumber(value) + ")"};
  }
  if (std::hypot(geo.f0.x - geo.e0.x, geo.f0.y - geo.e0.y) <= 0.0) {
    return LinkageDefect{"f0_mm", "beam pins E and F coincide (EF = L8 must be > 0)"};
  }
  if (std::hypot(geo.h0.x - geo.g0.x, geo.h0.y - geo.g0.y) <= 0.0) {
    return LinkageDefect{"h0_mm", "beam pins G and H coincide (|GH| must be > 0)"};
  }
  if (!(geo.beta_min_deg < geo.beta_max_deg) || geo.beta_min_deg < -180.0 ||
      geo.beta_max_deg > 180.0) {
    return LinkageDefect{"beta_max_deg",
                         "working range must satisfy -180 <= beta_min_deg < "
                         "beta_max_deg <= 180 (got [" +
                             FormatNumber(geo.beta_min_deg) + ", " +
                             FormatNumber(geo.beta_max_deg) + "])"};
  }
  const Linkage linkage = Linkage::Unchecked(geo);
  const double gh = std::hypot(geo.h0.x - geo.g0.x, geo.h0.y - geo.g0.y);
  for (int i = 0; i < kAssemblyGridPoints; ++i) {
    const double beta2 =
        geo.beta_min_deg + (geo.beta_max_deg - geo.beta_min_deg) * i / (kAssemblyGridPoints - 1);
    const double b2 = beta2 * std::numbers::pi / 180.0;
    const Vec2<double> j{geo.b.x + geo.bj_mm * std::cos(b2), geo.b.y + geo.bj_mm * std::sin(b2)};
    const double cj = std::hypot(j.x - geo.c.x, j.y - geo.c.y);
    if (cj > geo.cg_mm + geo.gj_mm || cj < std::abs(geo.cg_mm - geo.gj_mm)) {
      return LinkageDefect{"gj_mm", "rods cannot close: rod GJ (" + Describe("L2", geo.gj_mm) +
                                        ") and guide CG (" + Describe("L3", geo.cg_mm) +
                                        ") do not meet at beta2 = " + FormatNumber(beta2) +
                                        " deg, where |CJ| = " + FormatNumber(cj) +
                                        " mm lies outside [|L3 - L2|, L3 + L2]"};
    }
    for (int k = 0; k < kAssemblyGridPoints; ++k) {
      const double beta1 =
          geo.beta_min_deg + (geo.beta_max_deg - geo.beta_min_deg) * k / (kAssemblyGridPoints - 1);
      Intermesh<double> y;
      LinkagePose<double> pose;
      if (!linkage.Forward(beta1, beta2, &y, &pose)) {
        const double b1 = beta1 * std::numbers::pi / 180.0;
        const double kx = geo.a.x + geo.ak_mm * std::cos(b1);
        const double ky = geo.a.y + geo.ak_mm * std::sin(b1);
        return LinkageDefect{"hk_mm", "rods cannot close: rod HK (" + Describe("L6", geo.hk_mm) +
                                          ") cannot reach pin H (|GH| = " + FormatNumber(gh) +
                                          " mm) at beta1 = " + FormatNumber(beta1) +
                                          " deg, beta2 = " + FormatNumber(beta2) + " deg (K = (" +
                                          FormatNumber(kx) + ", " + FormatNumber(ky) + "))"};
      }
    }
  }
  return std::nullopt;
}

void ValidateLinkage(const LinkageGeometry& geometry, const std::string& where) {
  if (const auto defect = FindLinkageDefect(geometry)) {
    throw InputError(where + ": key '" + defect->key + "': " + defect->rule);
  }
}

namespace {

Point2 ReadPoint(const TomlSection& section, std::string_view key, Point2 fallback) {
  if (!section.Has(key)) return fallback;
  const auto values = section.NumberArray(key);
  if (values.size() != 2) section.Fail(key, "must be a point [x, y] in mm");
  return {values[0], values[1]};
}

void ReadLinkage(const TomlSection& s, LinkageGeometry* geo) {
  s.RequireOnlyKeys({"a_mm", "b_mm", "c_mm", "ak_mm", "bj_mm", "hk_mm", "gj_mm", "cg_mm", "e0_mm",
                     "f0_mm", "g0_mm", "h0_mm", "beta_min_deg", "beta_max_deg"});
  geo->a = ReadPoint(s, "a_mm", geo->a);
  geo->b = ReadPoint(s, "b_mm", geo->b);
  geo->c = ReadPoint(s, "c_mm", geo->c);
  geo->e0 = ReadPoint(s, "e0_mm", geo->e0);
  geo->f0 = ReadPoint(s, "f0_mm", geo->f0);
  geo->g0 = ReadPoint(s, "g0_mm", geo->g0);
  geo->h0 = ReadPoint(s, "h0_mm", geo->h0);
  geo->ak_mm = s.Positive("ak_mm", s.Number("ak_mm", geo->ak_mm));
  geo->bj_mm = s.Positive("bj_mm", s.Number("bj_mm", geo->bj_mm));
  geo->hk_mm = s.Positive("hk_mm", s.Number("hk_mm", geo->hk_mm));
  geo->gj_mm = s.Positive("gj_mm", s.Number("gj_mm", geo->gj_mm));
  geo->cg_mm = s.Positive("cg_mm", s.Number("cg_mm", geo->cg_mm));
  geo->beta_min_deg =
      s.InRange("beta_min_deg", s.Number("beta_min_deg", geo->beta_min_deg), -180.0, 180.0);
  geo->beta_max_deg =
      s.InRange("beta_max_deg", s.Number("beta_max_deg", geo->beta_max_deg), -180.0, 180.0);
  if (!(geo->beta_min_deg < geo->beta_max_deg)) {
    s.Fail("beta_max_deg", "must be > beta_min_deg (" + FormatNumber(geo->beta_min_deg) + ")");
  }
}

void ReadHydraulic(const TomlSection& s, HydraulicRange* range) {
  s.RequireOnlyKeys({"ah_min_mm", "ah_max_mm", "bg_min_mm", "bg_max_mm"});
  range->ah_min_mm = s.Positive("ah_min_mm", s.Number("ah_min_mm", range->ah_min_mm));
  range->ah_max_mm = s.Positive("ah_max_mm", s.Number("ah_max_mm", range->ah_max_mm));
  range->bg_min_mm = s.Positive("bg_min_mm", s.Number("bg_min_mm", range->bg_min_mm));
  range->bg_max_mm = s.Positive("bg_max_mm", s.Number("bg_max_mm", range->bg_max_mm));
  if (!(range->ah_min_mm < range->ah_max_mm)) s.Fail("ah_max_mm", "must be > ah_min_mm");
  if (!(range->bg_min_mm < range->bg_max_mm)) s.Fail("bg_max_mm", "must be > bg_min_mm");
}

void ReadRolls(const TomlSection& s, LevellerConfig* config) {
  s.RequireOnlyKeys({"diameter_mm", "pitch_mm", "lower_y_mm", "count"});
  auto& m = config->machine;
  m.roll_diameter_mm = s.Positive("diameter_mm", s.Number("diameter_mm", m.roll_diameter_mm));
  m.pitch_mm = s.Positive("pitch_mm", s.Number("pitch_mm", m.pitch_mm));
  config->linkage.lower_y_mm = s.Number("lower_y_mm", config->linkage.lower_y_mm);
  const double count = s.Number("count", m.roll_count);
  if (count != 7.0)
    s.Fail("count", "only seven-roll levellers are modelled (got " + FormatNumber(count) + ")");
}

void ReadMachine(const TomlSection& s, MachineData* m) {
  s.RequireOnlyKeys({"bearing_diameter_mm", "rolling_friction_arm_mm", "bearing_friction",
                     "speed_m_per_s", "efficiency", "motor_power_kW", "max_roll_force_kN",
                     "max_total_force_kN"});
  m->bearing_diameter_mm =
      s.Positive("bearing_diameter_mm", s.Number("bearing_diameter_mm", m->bearing_diameter_mm));
  m->rolling_friction_arm_mm = s.NonNegative(
      "rolling_friction_arm_mm", s.Number("rolling_friction_arm_mm", m->rolling_friction_arm_mm));
  m->bearing_friction =
      s.NonNegative("bearing_friction", s.Number("bearing_friction", m->bearing_friction));
  m->speed_m_per_s = s.Positive("speed_m_per_s", s.Number("speed_m_per_s", m->speed_m_per_s));
  m->efficiency = s.Number("efficiency", m->efficiency);
  if (!(m->efficiency > 0.0 && m->efficiency <= 1.0)) {
    s.Fail("efficiency", "must be in (0, 1] (got " + FormatNumber(m->efficiency) + ")");
  }
  m->motor_power_kW = s.Positive("motor_power_kW", s.Number("motor_power_kW", m->motor_power_kW));
  m->max_roll_force_kN =
      s.Positive("max_roll_force_kN", s.Number("max_roll_force_kN", m->max_roll_force_kN));
  m->max_total_force_kN =
      s.Positive("max_total_force_kN", s.Number("max_total_force_kN", m->max_total_force_kN));
}

}  // namespace

LevellerConfig LoadLevellerConfig(const std::filesystem::path& path) {
  const toml::table document = LoadTomlFile(path);
  const TomlSection root(document, path.string(), "");
  root.RequireOnlyKeys({"linkage", "hydraulic", "rolls", "machine"});
  LevellerConfig config;
  config.source = path.string();
  std::optional<TomlSection> linkage = root.OptionalTable("linkage");
  if (linkage) ReadLinkage(*linkage, &config.linkage);
  if (auto hydraulic = root.OptionalTable("hydraulic"))
    ReadHydraulic(*hydraulic, &config.hydraulic);
  if (auto rolls = root.OptionalTable("rolls")) ReadRolls(*rolls, &config);
  if (auto machine = root.OptionalTable("machine")) ReadMachine(*machine, &config.machine);
  config.linkage.roll_diameter_mm = config.machine.roll_diameter_mm;
  if (const auto defect = FindLinkageDefect(config.linkage)) {
    if (linkage && linkage->Has(defect->key)) linkage->Fail(defect->key, defect->rule);
    throw InputError(path.string() + ": [linkage] key '" + defect->key + "': " + defect->rule);
  }
  return config;
}

LevellerConfig DefaultLevellerConfig() {
  LevellerConfig config;
  ValidateLinkage(config.linkage, config.source);
  return config;
}

}  // namespace millkit::leveller
