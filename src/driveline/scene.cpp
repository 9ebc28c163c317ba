#include "millkit/driveline/scene.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include "io/toml_section.h"
#include "millkit/driveline/model.h"
#include "millkit/io/csv.h"
#include "millkit/io/input_error.h"

namespace millkit::driveline {

double TorqueSource::ValueAt(double t) const {
  if (times_s.empty()) return 0.0;
  if (t < times_s.front()) return values_Nm.front();
  // Right-continuous: the last knot with time <= t starts the segment.
  const auto it = std::upper_bound(times_s.begin(), times_s.end(), t);
  const size_t i = static_cast<size_t>(it - times_s.begin()) - 1;
  if (i + 1 >= times_s.size()) return values_Nm.back();
  const double span = times_s[i + 1] - times_s[i];
  if (span <= 0.0) return values_Nm[i + 1];
  return values_Nm[i] + (values_Nm[i + 1] - values_Nm[i]) * (t - times_s[i]) / span;
}

double TorqueSource::SlopeAt(double t) const {
  if (times_s.empty() || t < times_s.front()) return 0.0;
  const auto it = std::upper_bound(times_s.begin(), times_s.end(), t);
  const size_t i = static_cast<size_t>(it - times_s.begin()) - 1;
  if (i + 1 >= times_s.size()) return 0.0;
  const double span = times_s[i + 1] - times_s[i];
  if (span <= 0.0) return 0.0;
  return (values_Nm[i + 1] - values_Nm[i]) / span;
}

int Scene::MassIndex(const std::string& mass_name) const {
  for (size_t i = 0; i < masses.size(); ++i) {
    if (masses[i].name == mass_name) return static_cast<int>(i);
  }
  return -1;
}

int Scene::LinkIndex(const std::string& link_name) const {
  for (size_t i = 0; i < links.size(); ++i) {
    if (links[i].name == link_name) return static_cast<int>(i);
  }
  return -1;
}

std::vector<double> Scene::InputBreakpoints() const {
  std::vector<double> points;
  for (const auto& source : torques) {
    for (double t : source.times_s) {
      if (t > 0.0 && t < duration_s) points.push_back(t);
    }
  }
  std::sort(points.begin(), points.end());
  points.erase(std::unique(points.begin(), points.end()), points.end());
  return points;
}

int Scene::SampleCount() const {
  return static_cast<int>(std::floor(duration_s * sample_rate_Hz * (1.0 + 1e-12))) + 1;
}

namespace {

std::string Quote(const std::string& s) { return "'" + s + "'"; }

// The message is built only for a broken rule: a fit validates a scene for every run.
template <typename Message>
void Require(bool ok, const Message& message) {
  if (!ok) throw InputError(message());
}

TorqueSource ReadTorqueTable(const TomlSection& section, const std::string& table_path,
                             const std::filesystem::path& scene_dir) {
  std::filesystem::path path(table_path);
  if (path.is_relative()) path = scene_dir / path;
  const CsvTable table = ReadCsv(path);
  if (table.columns.size() != 2 || table.columns[0] != "time") {
    section.Fail("table", path.string() + " must have exactly two columns: time,<torque>");
  }
  if (table.rows.empty()) section.Fail("table", path.string() + " has no data rows");
  // A units row may say what the table holds, not change it.
  RequireUnits(table, {{"time", {"s"}}, {table.columns[1], {"N*m", "Nm", "N·m"}}});
  RequireStrictlyIncreasing(table, 0);
  TorqueSource source;
  source.times_s = table.ColumnValues(0);
  source.values_Nm = table.ColumnValues(1);
  return source;
}

}  // namespace

Scene LoadScene(const std::string& path) {
  const toml::table document = LoadTomlFile(path);
  const TomlSection root(document, path, "");
  root.RequireOnlyKeys({"scene", "initial", "mass", "link", "torque", "drive"});
  const std::filesystem::path scene_dir = std::filesystem::path(path).parent_path();

  Scene scene;
  scene.file = path;
  const auto scene_section = root.OptionalTable("scene");
  if (!scene_section) root.Fail("scene", "the table [scene] is required");
  scene_section->RequireOnlyKeys({"name", "duration", "sample_rate", "contact", "band"});
  scene.name = scene_section->String("name", std::filesystem::path(path).stem().string());
  scene.duration_s = scene_section->Positive("duration", scene_section->RequiredNumber("duration"));
  scene.sample_rate_Hz =
      scene_section->Positive("sample_rate", scene_section->RequiredNumber("sample_rate"));
  if (scene.duration_s * scene.sample_rate_Hz > 5e7) {
    scene_section->Fail("sample_rate", "duration·sample_rate exceeds 5e7 samples");
  }
  const std::string law = scene_section->String("contact", "limited");
  if (!ParseContactLaw(law, &scene.contact)) {
    scene_section->Fail("contact", "must be limited, no_pull or linear (got '" + law + "')");
  }
  if (const auto band = scene_section->OptionalNumber("band")) {
    scene.band_Hz = scene_section->Positive("band", *band);
  }

  const auto initial = root.OptionalTable("initial");
  if (initial) {
    initial->RequireOnlyKeys({"speed"});
    scene.initial_speed_rad_per_s = initial->Number("speed", 0.0);
  }

  for (const auto& m : root.TableArray("mass")) {
    m.RequireOnlyKeys({"name", "inertia"});
    Mass mass;
    mass.name = m.RequiredString("name");
    if (scene.MassIndex(mass.name) >= 0) m.Fail("name", "mass " + Quote(mass.name) + " repeated");
    mass.inertia_kg_m2 = m.Positive("inertia", m.RequiredNumber("inertia"));
    scene.masses.push_back(mass);
  }
  if (scene.masses.empty()) root.Fail("mass", "at least one [[mass]] is required");

  auto mass_of = [&](const TomlSection& s, std::string_view key, const std::string& name) {
    const int index = scene.MassIndex(name);
    if (index < 0) s.Fail(key, "no [[mass]] named " + Quote(name));
    return index;
  };

  for (const auto& l : root.TableArray("link")) {
    l.RequireOnlyKeys(
        {"name", "between", "stiffness", "damping", "backlash", "gap_position", "ratio"});
    Link link;
    link.name = l.RequiredString("name");
    if (scene.LinkIndex(link.name) >= 0) l.Fail("name", "link " + Quote(link.name) + " repeated");
    const auto between = l.RequiredStringArray("between");
    if (between.size() != 2) l.Fail("between", "must name two masses: [from, to]");
    link.from = mass_of(l, "between", between[0]);
    link.to = mass_of(l, "between", between[1]);
    if (link.from == link.to) l.Fail("between", "a link cannot join a mass to itself");
    link.stiffness_Nm_per_rad = l.Positive("stiffness", l.RequiredNumber("stiffness"));
    link.damping_Nms_per_rad = l.NonNegative("damping", l.Number("damping", 0.0));
    link.backlash_rad = l.NonNegative("backlash", l.Number("backlash", 0.0));
    link.gap_position = l.InRange("gap_position", l.Number("gap_position", -1.0), -1.0, 1.0);
    link.ratio = l.Positive("ratio", l.Number("ratio", 1.0));
    scene.links.push_back(link);
  }

  for (const auto& t : root.TableArray("torque")) {
    t.RequireOnlyKeys({"at", "before", "after", "start", "rise", "table"});
    TorqueSource source;
    const std::string at = t.RequiredString("at");
    source.mass = mass_of(t, "at", at);
    source.name = "[[torque]] at " + at;
    if (const auto table = t.OptionalString("table")) {
      for (const char* key : {"before", "after", "start", "rise"}) {
        if (t.Has(key)) t.Fail(key, "give either table or before/after/start/rise, not both");
      }
      const TorqueSource read = ReadTorqueTable(t, *table, scene_dir);
      source.times_s = read.times_s;
      source.values_Nm = read.values_Nm;
    } else {
      const double before = t.Number("before", 0.0);
      const double after = t.RequiredNumber("after");
      const double start = t.NonNegative("start", t.Number("start", 0.0));
      const double rise = t.NonNegative("rise", t.Number("rise", 0.0));
      source.times_s = {start, start + rise};
      source.values_Nm = {before, after};
    }
    scene.torques.push_back(source);
  }

  if (const auto d = root.OptionalTable("drive")) {
    d->RequireOnlyKeys({"at", "speed_ref", "kp", "ki", "lag", "limit"});
    Drive drive;
    drive.mass = mass_of(*d, "at", d->RequiredString("at"));
    drive.speed_ref_rad_per_s = d->Number("speed_ref", scene.initial_speed_rad_per_s);
    drive.kp = d->NonNegative("kp", d->RequiredNumber("kp"));
    drive.ki = d->NonNegative("ki", d->RequiredNumber("ki"));
    if (drive.kp == 0.0 && drive.ki == 0.0) d->Fail("kp", "kp and ki cannot both be 0");
    drive.lag_s = d->Positive("lag", d->RequiredNumber("lag"));
    drive.limit_Nm = d->Positive("limit", d->RequiredNumber("limit"));
    scene.drive = drive;
  }

  ValidateScene(scene);
  return scene;
}

void ValidateScene(const Scene& scene) {
  const std::string& file = scene.file.empty() ? std::string("<scene>") : scene.file;
  const int n = static_cast<int>(scene.masses.size());
  Require(n >= 1, [&] { return file + ": at least one [[mass]] is required"; });
  Require(scene.duration_s > 0.0, [&] { return file + ": [scene] key 'duration': must be > 0"; });
  Require(scene.sample_rate_Hz > 0.0,
          [&] { return file + ": [scene] key 'sample_rate': must be > 0"; });
  for (const auto& m : scene.masses) {
    Require(m.inertia_kg_m2 > 0.0 && std::isfinite(m.inertia_kg_m2),
            [&] { return file + ": mass " + Quote(m.name) + " key 'inertia': must be > 0"; });
  }
  for (const auto& l : scene.links) {
    const auto where = [&] { return file + ": link " + Quote(l.name); };
    Require(l.from >= 0 && l.from < n && l.to >= 0 && l.to < n && l.from != l.to,
            [&] { return where() + " key 'between': must join two different masses"; });
    Require(l.stiffness_Nm_per_rad > 0.0 && std::isfinite(l.stiffness_Nm_per_rad),
            [&] { return where() + " key 'stiffness': must be > 0"; });
    Require(l.damping_Nms_per_rad >= 0.0 && std::isfinite(l.damping_Nms_per_rad),
            [&] { return where() + " key 'damping': must be >= 0"; });
    Require(l.backlash_rad >= 0.0 && std::isfinite(l.backlash_rad),
            [&] { return where() + " key 'backlash': must be >= 0"; });
    Require(l.gap_position >= -1.0 && l.gap_position <= 1.0,
            [&] { return where() + " key 'gap_position': must lie in [-1, 1]"; });
    Require(l.recorder_lowpass_Hz >= 0.0 && std::isfinite(l.recorder_lowpass_Hz),
            [&] { return where() + " recorder low-pass: must be >= 0 Hz and finite"; });
    Require(l.ratio > 0.0 && std::isfinite(l.ratio), [&] {
      return where() + " key 'ratio': must be > 0 (i = ω_from / ω_to; got " +
             FormatNumber(l.ratio) + ")";
    });
  }
  // Tree: n − 1 links that connect all masses (hence no cycle).
  Require(static_cast<int>(scene.links.size()) == n - 1, [&] {
    return file + ": [[link]]: the masses and links must form a tree (" + std::to_string(n) +
           " masses need exactly " + std::to_string(n - 1) + " links, got " +
           std::to_string(scene.links.size()) + ")";
  });
  std::vector<int> parent(n);
  for (int i = 0; i < n; ++i) parent[i] = i;
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (const auto& l : scene.links) {
    const int a = find(l.from), b = find(l.to);
    Require(a != b, [&] {
      return file + ": link " + Quote(l.name) +
             " key 'between': closes a loop; the masses and links must form a tree";
    });
    parent[a] = b;
  }
  for (const auto& s : scene.torques) {
    Require(s.mass >= 0 && s.mass < n, [&] { return file + ": " + s.name + ": unknown mass"; });
    Require(!s.times_s.empty() && s.times_s.size() == s.values_Nm.size(),
            [&] { return file + ": " + s.name + ": needs at least one (time, value) knot"; });
    for (size_t i = 0; i < s.times_s.size(); ++i) {
      Require(std::isfinite(s.times_s[i]) && std::isfinite(s.values_Nm[i]),
              [&] { return file + ": " + s.name + ": knots must be finite"; });
      if (i > 0) {
        Require(s.times_s[i] >= s.times_s[i - 1],
                [&] { return file + ": " + s.name + ": knot times must not decrease"; });
      }
    }
  }
  if (scene.drive) {
    const Drive& d = *scene.drive;
    Require(d.mass >= 0 && d.mass < n, [&] { return file + ": [drive] key 'at': unknown mass"; });
    Require(d.kp >= 0.0 && d.ki >= 0.0 && d.kp + d.ki > 0.0,
            [&] { return file + ": [drive] keys 'kp', 'ki': must be >= 0 and not both 0"; });
    Require(d.lag_s > 0.0, [&] { return file + ": [drive] key 'lag': must be > 0"; });
    Require(d.limit_Nm > 0.0, [&] { return file + ": [drive] key 'limit': must be > 0"; });
  }
  CheckSampleRate(scene);
}

double QuasiStaticTwist(const Link& link, double torque_Nm) {
  return 0.5 * link.backlash_rad + std::abs(torque_Nm) / link.stiffness_Nm_per_rad;
}

ShaftFactors ComputeShaftFactors(const Scene& scene) {
  const int n = static_cast<int>(scene.masses.size());
  ShaftFactors factors;
  factors.mass.assign(n, 1.0);
  for (int l = 0; l < static_cast<int>(scene.links.size()); ++l) {
    const Link& gear = scene.links[l];
    if (gear.ratio == 1.0) continue;
    factors.identity = false;
    // The masses beyond `from`: the part of the tree reached from it without crossing the link.
    std::vector<char> seen(n, 0);
    std::vector<int> stack{gear.from};
    seen[gear.from] = 1;
    seen[gear.to] = 1;  // the link itself is not crossed
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      factors.mass[i] *= gear.ratio;
      for (int m = 0; m < static_cast<int>(scene.links.size()); ++m) {
        if (m == l) continue;
        const Link& link = scene.links[m];
        const int other = link.from == i ? link.to : link.to == i ? link.from : -1;
        if (other >= 0 && !seen[other]) {
          seen[other] = 1;
          stack.push_back(other);
        }
      }
    }
  }
  factors.link.resize(scene.links.size());
  for (size_t l = 0; l < scene.links.size(); ++l) {
    factors.link[l] = factors.mass[scene.links[l].to];
  }
  return factors;
}

Scene ReducedScene(const Scene& scene) {
  const ShaftFactors k = ComputeShaftFactors(scene);
  Scene reduced = scene;
  if (k.identity) return reduced;
  for (size_t i = 0; i < scene.masses.size(); ++i) {
    reduced.masses[i].inertia_kg_m2 *= k.mass[i] * k.mass[i];
  }
  for (size_t l = 0; l < scene.links.size(); ++l) {
    Link& link = reduced.links[l];
    const double f = k.link[l];
    link.stiffness_Nm_per_rad *= f * f;
    link.damping_Nms_per_rad *= f * f;
    link.backlash_rad /= f;
    link.ratio = 1.0;
  }
  for (auto& source : reduced.torques) {
    for (double& value : source.values_Nm) value *= k.mass[source.mass];
  }
  if (reduced.drive) {
    Drive& drive = *reduced.drive;
    const double f = k.mass[drive.mass];
    drive.speed_ref_rad_per_s /= f;
    drive.kp *= f * f;
    drive.ki *= f * f;
    drive.limit_Nm *= f;
  }
  return reduced;
}

}  // namespace millkit::driveline
