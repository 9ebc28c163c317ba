// Identification campaigns (issue 15 item 3): a manifest of records over weeks, each fitted, the
// gap's wear trend recovered; failed rows reported in place; a bad manifest stops before any
// output; the same numbers on any thread count.
#include "millkit/identify/campaign.h"

#include <unistd.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "identify/campaign_line.h"
#include "millkit/driveline/scene.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/identify/record_generator.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

namespace millkit::identify {
namespace {

using Catch::Matchers::Contains;
using millkit::testing::ReadText;
using millkit::testing::RunMillkit;
using millkit::testing::ScratchDir;
using millkit::testing::Shell;
using millkit::testing::WriteText;

// The line and its truth: identify/campaign_line.h.
constexpr const char* kScene = kCampaignLineScene;
constexpr double kGapAtDay0_rad = kCampaignGapAtDay0_rad;
constexpr double kWearPerDay_rad = kCampaignWearPerDay_rad;
constexpr double kTrueDamping = kCampaignTrueDamping;
// Record times as a logger would stamp them, and their days after the first (by hand).
struct Stamp {
  const char* iso;
  double day;
};
constexpr Stamp kStamps[] = {
    {"2026-01-05", 0.0},         {"2026-01-15T08:00:00", 10.0 + 8.0 / 24.0}, {"2026-01-25", 20.0},
    {"2026-02-04T12:00Z", 30.5}, {"2026-02-14T06:00:00+06:00", 40.0},        {"2026-02-24", 50.0}};
// Each ok fit lands within this many standard errors of its truth (as the bundled record's test
// in identify_cli_test.cpp); the trend's slope within the 3.
constexpr double kValueSe = 4.0;
constexpr double kSlopeSe = 3.0;

double TrueGap(double day) { return kGapAtDay0_rad + kWearPerDay_rad * day; }

// A record of the line with the gap of `day` (identify/campaign_line.h).
std::string RecordCsv(const driveline::Scene& prior, double day, unsigned long seed) {
  return CampaignLineRecordCsv(prior, TrueGap(day), seed);
}

// The scene, six records and their manifest in a scratch directory (records in a subdirectory:
// manifest paths are relative to the manifest).
struct Campaign {
  ScratchDir dir;
  std::string scene_path = (dir / "scene.toml").string();
  std::string manifest_path = (dir / "manifest.csv").string();
  driveline::Scene scene;

  explicit Campaign(const std::string& extra_rows = "") {
    WriteText(scene_path, kScene);
    scene = driveline::LoadScene(scene_path);
    std::filesystem::create_directories(dir / "records");
    std::string manifest = "file,time,stand\n";
    for (size_t k = 0; k < std::size(kStamps); ++k) {
      const std::string file = "records/r" + std::to_string(k) + ".csv";
      WriteText(dir / file, RecordCsv(scene, kStamps[k].day, 100 + k));
      manifest += file + "," + kStamps[k].iso + ",F1\n";
    }
    WriteText(manifest_path, manifest + extra_rows);
  }
  std::string Cli(const std::string& options) const {
    return "identify '" + scene_path + "' --campaign '" + manifest_path + "' --quiet " + options;
  }
};

int ParameterIndex(const CampaignResult& result, const std::string& name) {
  for (size_t p = 0; p < result.parameters.size(); ++p) {
    if (result.parameters[p].name == name) return static_cast<int>(p);
  }
  return -1;
}

}  // namespace

TEST_CASE("ISO 8601 dates and date-times read as UTC seconds, impossible ones are refused",
          "[campaign]") {
  // 946684800 s: the Unix time of 2000-01-01T00:00:00Z (POSIX `date -u -d 2000-01-01 +%s`).
  constexpr double k2000 = 946684800.0;
  CHECK(ParseIsoTime("1970-01-01") == 0.0);
  CHECK(ParseIsoTime("2000-01-01") == k2000);
  CHECK(ParseIsoTime("2000-01-01T00:00:00Z") == k2000);
  CHECK(ParseIsoTime("2000-01-01 01:30") == k2000 + 5400.0);
  CHECK(ParseIsoTime("2000-01-01T02:00:15+02:00") == k2000 + 15.0);
  CHECK(ParseIsoTime("1999-12-31T19:00:00-0500") == k2000);
  CHECK(ParseIsoTime("2000-01-01T00:00:00.25") == k2000 + 0.25);
  CHECK(ParseIsoTime("2000-03-01").value() - ParseIsoTime("2000-02-28").value() ==
        2 * 86400.0);  // 2000 is a leap year
  CHECK(ParseIsoTime("2024-02-29"));
  for (const char* bad : {"2023-02-29", "2026-13-01", "2026-04-31", "2026-1-5", "05.01.2026",
                          "2026-01-05T24:00", "2026-01-05T08:60", "2026-01-05T08", "2026-01-05x",
                          "2026-01-05T08:00:00+2", "yesterday", ""}) {
    INFO(bad);
    CHECK_FALSE(ParseIsoTime(bad));
  }
}

TEST_CASE("a synthetic campaign recovers each record's gap and the wear slope", "[campaign]") {
  const Campaign campaign;
  const CampaignManifest manifest =
      LoadCampaignManifest(campaign.manifest_path, /*config=*/"", /*time_column=*/"");
  REQUIRE(manifest.rows.size() == std::size(kStamps));
  REQUIRE(manifest.fits.size() == std::size(kStamps));
  const CampaignResult result = RunCampaign(campaign.scene, manifest, CampaignOptions{});
  CHECK(result.AllOk());
  const int gap = ParameterIndex(result, "spindle.backlash");
  const int damping = ParameterIndex(result, "spindle.damping");
  REQUIRE(gap >= 0);
  REQUIRE(damping >= 0);
  CHECK(result.parameters[gap].unit == "rad");
  CHECK(result.parameters[gap].link == "spindle");
  CHECK(result.parameters[ParameterIndex(result, "bite_time")].link.empty());
  for (size_t r = 0; r < result.rows.size(); ++r) {
    const auto& row = result.rows[r];
    INFO("row " << r << ": " << row.verdict << " " << row.reason);
    REQUIRE(row.verdict == "ok");
    CHECK_THAT(FitDay(manifest, row.fit), Catch::Matchers::WithinAbs(kStamps[r].day, 1e-9));
    CHECK(std::abs(row.value[gap] - TrueGap(kStamps[r].day)) <= kValueSe * row.standard_error[gap]);
    CHECK(std::abs(row.value[damping] - kTrueDamping) <= kValueSe * row.standard_error[damping]);
  }
  // One trend per link parameter (damping and gap) of the one stand.
  REQUIRE(result.trends.size() == 2);
  const TrendLine& wear = result.trends[gap < damping ? 0 : 1];
  REQUIRE(wear.parameter == "spindle.backlash");
  REQUIRE(wear.defined);
  CHECK(wear.points == 6);
  CHECK(wear.slope_se > 0.0);
  CHECK(std::abs(wear.slope_per_day - kWearPerDay_rad) <= kSlopeSe * wear.slope_se);
  CHECK(std::abs(wear.value_at_epoch - kGapAtDay0_rad) <= kSlopeSe * wear.value_at_epoch_se);
  // The damping does not wear: its slope is zero within its error.
  const TrendLine& flat = result.trends[gap < damping ? 1 : 0];
  CHECK(std::abs(flat.slope_per_day) <= kSlopeSe * flat.slope_se);
}

TEST_CASE("a campaign gives the same table and trends on 1 and 2 threads", "[campaign]") {
  const Campaign campaign;
  const CampaignManifest manifest = LoadCampaignManifest(campaign.manifest_path, "", "");
  CampaignOptions options;
  const CampaignResult one = RunCampaign(campaign.scene, manifest, options);
  options.threads = 2;
  const CampaignResult two = RunCampaign(campaign.scene, manifest, options);
  CHECK(CampaignCsv(manifest, one) == CampaignCsv(manifest, two));
  CHECK(CampaignTrendCsv(manifest, one) == CampaignTrendCsv(manifest, two));
  REQUIRE(one.trends.size() == two.trends.size());
  for (size_t t = 0; t < one.trends.size(); ++t) {
    CHECK(one.trends[t].slope_per_day == two.trends[t].slope_per_day);
    CHECK(one.trends[t].slope_se == two.trends[t].slope_se);
  }
}

TEST_CASE("rows of one group are one fit: a shared gap, a bite time per record", "[campaign]") {
  const Campaign campaign;
  // A second bite of day 20 (other noise) grouped with the first one, half a day later.
  WriteText(campaign.dir / "records/r2b.csv", RecordCsv(campaign.scene, 20.0, 200));
  WriteText(campaign.manifest_path,
            "file,time,stand,group\n"
            "records/r0.csv,2026-01-05,F1,\n"
            "records/r2.csv,2026-01-25,F1,week4\n"
            "records/r2b.csv,2026-01-25T12:00,F1,week4\n");
  const CampaignManifest manifest = LoadCampaignManifest(campaign.manifest_path, "", "");
  REQUIRE(manifest.fits.size() == 2);
  CHECK(manifest.fits[1] == std::vector<int>{1, 2});
  CHECK_THAT(FitDay(manifest, 1), Catch::Matchers::WithinAbs(20.25, 1e-9));
  const CampaignResult result = RunCampaign(campaign.scene, manifest, CampaignOptions{});
  const int gap = ParameterIndex(result, "spindle.backlash");
  const int bite = ParameterIndex(result, "bite_time");
  REQUIRE(gap >= 0);
  REQUIRE(bite >= 0);
  const auto& a = result.rows[1];
  const auto& b = result.rows[2];
  INFO(a.verdict << ": " << a.reason);
  CHECK(a.fit == b.fit);
  REQUIRE(a.verdict == "ok");
  CHECK(b.verdict == "ok");
  CHECK(std::abs(a.value[gap] - TrueGap(20.0)) <= kValueSe * a.standard_error[gap]);
  CHECK(a.value[gap] == b.value[gap]);
  CHECK(a.value[bite] != b.value[bite]);  // each record's own bite time
  CHECK(std::isfinite(a.value[bite]));
}

TEST_CASE("a missing and a corrupt record are reported in their rows, and the campaign exits 3",
          "[campaign]") {
  const Campaign campaign(
      "records/gone.csv,2026-03-01,F1\nrecords/bad.csv,2026-03-02,F1\n"
      "records/loop.csv,2026-03-03,F1\n");
  WriteText(campaign.dir / "records/bad.csv", "time,spindle\n0,1\n0.001,abc\n");
  // A link to itself: once an internal error that stopped the campaign.
  std::filesystem::create_symlink("loop.csv", campaign.dir / "records/loop.csv");
  const auto out = campaign.dir / "out";
  std::filesystem::create_directories(out);
  const auto result = RunMillkit(campaign.Cli(
      "--out '" + (out / "campaign.csv").string() + "' --trend '" + (out / "trend.csv").string() +
      "' --plot '" + (out / "trend").string() + "' --threads 2"));
  INFO(result.stderr_text);
  REQUIRE(result.exit_code == 3);
  CHECK_THAT(result.stderr_text, Contains("line 8 (records/gone.csv): failed"));
  CHECK_THAT(result.stderr_text, Contains("3 of 9 records not ok"));
  const std::string table = ReadText(out / "campaign.csv");
  CHECK_THAT(table, Contains("\"records/gone.csv\",\"2026-03-01\",\"F1\",\"\",failed,\""));
  CHECK_THAT(table, Contains("gone.csv: file not found"));
  CHECK_THAT(table, Contains("\"records/bad.csv\",\"2026-03-02\",\"F1\",\"\",failed,\""));
  CHECK_THAT(table, Contains("bad.csv: line 3, column 'spindle': 'abc' is not a finite number"));
  CHECK_THAT(table, Contains("\"records/loop.csv\",\"2026-03-03\",\"F1\",\"\",failed,\""));
  CHECK_THAT(table, Contains("loop.csv: cannot be read"));
  CHECK_THAT(table, Contains("\"spindle.backlash [rad]\",\"spindle.backlash.se [rad]\""));
  int ok_rows = 0;
  for (auto at = table.find(",ok,"); at != std::string::npos; at = table.find(",ok,", at + 1)) {
    ++ok_rows;
  }
  CHECK(ok_rows == 6);
  CHECK_THAT(ReadText(out / "trend.csv"), Contains("\"F1\",spindle.backlash,\"rad\",6,"));
  const std::string svg = ReadText(out / "trend.spindle.svg");
  CHECK_THAT(svg, Contains("class=\"error-bars\""));
  CHECK_THAT(svg, Contains("days since 2026-01-05"));
  CHECK_THAT(svg, Contains("F1, spindle.backlash: trend"));
  CHECK(campaign.dir.EntryCount() == 4);  // scene, manifest, records, out: no temporary left
}

TEST_CASE("a bad manifest exits 2 naming its line and column, and writes nothing", "[campaign]") {
  struct Case {
    const char* what;
    std::string manifest;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"no stand column", "file,time\nrecords/r0.csv,2026-01-05\n",
       "manifest.csv: line 1: the header has no column 'stand'"},
      {"a date that does not exist",
       "file,time,stand\nrecords/r0.csv,2026-01-05,F1\n"
       "records/r1.csv,2026-02-30,F1\n",
       "manifest.csv: line 3, column 'time': '2026-02-30' is not an ISO 8601 date"},
      {"an empty file cell", "file,time,stand\n# a comment line\n,2026-01-05,F1\n",
       "manifest.csv: line 3, column 'file': empty"},
      {"a stand that is not a name", "file,time,stand\nrecords/r0.csv,2026-01-05,F1/upper\n",
       "manifest.csv: line 2, column 'stand': 'F1/upper' is not a stand name"},
      {"an unknown column", "file,time,stand,remark\nrecords/r0.csv,2026-01-05,F1,new\n",
       "manifest.csv: line 1, column 'remark': unknown column"},
      {"a config that does not exist",
       "file,time,stand,config\nrecords/r0.csv,2026-01-05,F1,"
       "nofit.toml\n",
       "manifest.csv: line 2, column 'config'"},
  };
  const Campaign campaign;
  for (const auto& c : cases) {
    INFO(c.what);
    WriteText(campaign.manifest_path, c.manifest);
    const auto out = campaign.dir / "out";
    std::filesystem::create_directories(out);
    const auto result = RunMillkit(campaign.Cli("--out '" + (out / "campaign.csv").string() +
                                                "' --trend '" + (out / "trend.csv").string() +
                                                "' --plot '" + (out / "trend").string() + "'"));
    CHECK(result.exit_code == 2);
    CHECK_THAT(result.stderr_text, Contains(c.message));
    CHECK(std::filesystem::is_empty(out));
  }
}

TEST_CASE("identify takes --data or --campaign, not both, and lists --campaign in its help",
          "[campaign]") {
  const Campaign campaign;
  const auto both =
      RunMillkit(campaign.Cli("--data '" + (campaign.dir / "records/r0.csv").string() +
                              "' --out '" + (campaign.dir / "c.csv").string() + "'"));
  CHECK(both.exit_code == 2);
  CHECK_THAT(both.stderr_text, Contains("give either --data"));
  CHECK_FALSE(std::filesystem::exists(campaign.dir / "c.csv"));
  const auto help = RunMillkit("identify --help");
  CHECK(help.exit_code == 0);
  CHECK_THAT(help.stdout_text, Contains("--campaign"));
  CHECK_THAT(help.stdout_text, Contains("--trend"));
}

TEST_CASE("an output that is the manifest or a record is refused before any fit", "[campaign]") {
  const Campaign campaign;
  const auto onto_record =
      RunMillkit(campaign.Cli("--out '" + (campaign.dir / "records/r3.csv").string() + "'"));
  CHECK(onto_record.exit_code == 2);
  CHECK_THAT(onto_record.stderr_text, Contains("an output never replaces an input"));
  const auto onto_manifest = RunMillkit(campaign.Cli("--out '" + campaign.manifest_path + "'"));
  CHECK(onto_manifest.exit_code == 2);
  CHECK_THAT(ReadText(campaign.manifest_path), Contains("file,time,stand"));
}

// Shards, merges and MPI ranks (issue 15 item 4): the same files as one run, byte for byte.

namespace {

// The outputs of one campaign run under `dir/name`: table, trend and the spindle's plot.
struct Outputs {
  std::filesystem::path dir;
  std::string Options() const {
    return "--out '" + (dir / "campaign.csv").string() + "' --trend '" +
           (dir / "trend.csv").string() + "' --plot '" + (dir / "trend").string() + "'";
  }
  void RequireSame(const Outputs& serial) const {
    for (const char* file : {"campaign.csv", "trend.csv", "trend.spindle.svg"}) {
      INFO(file);
      REQUIRE(std::filesystem::exists(serial.dir / file));
      CHECK(ReadText(dir / file) == ReadText(serial.dir / file));
    }
  }
};

Outputs MakeOutputs(const Campaign& campaign, const std::string& name) {
  Outputs outputs{campaign.dir / name};
  std::filesystem::create_directories(outputs.dir);
  return outputs;
}

// A campaign with a failed row (a missing record): failed rows travel between ranks and parts
// too; the serial run exits 3.
constexpr const char* kGoneRow = "records/gone.csv,2026-03-01,F1\n";

}  // namespace

TEST_CASE("shards 1/2 and 2/2 merged write the same table, trend and plots as one run",
          "[campaign][shard]") {
  const Campaign campaign(kGoneRow);
  const Outputs serial = MakeOutputs(campaign, "serial");
  const auto one = RunMillkit(campaign.Cli(serial.Options()));
  INFO(one.stderr_text);
  REQUIRE(one.exit_code == 3);
  const auto parts = campaign.dir / "parts";
  std::filesystem::create_directories(parts);
  for (const char* k : {"1", "2"}) {
    const auto shard =
        RunMillkit(campaign.Cli("--shard " + std::string(k) + "/2 --out '" +
                                (parts / ("part-" + std::string(k) + ".csv")).string() + "'"));
    INFO(shard.stderr_text);
    // Fits 0, 2, 4, 6 (the gone record is fit 6) and 1, 3, 5: shard 1 has the failed row.
    CHECK(shard.exit_code == (k == std::string("1") ? 3 : 0));
  }
  // Parts in either order give the same files.
  const Outputs merged = MakeOutputs(campaign, "merged");
  const auto merge =
      RunMillkit(campaign.Cli("--merge '" + (parts / "part-2.csv").string() + "' '" +
                              (parts / "part-1.csv").string() + "' " + merged.Options()));
  INFO(merge.stderr_text);
  CHECK(merge.exit_code == 3);
  merged.RequireSame(serial);
  CHECK(merge.stdout_text.substr(merge.stdout_text.find('\n')) ==
        one.stdout_text.substr(one.stdout_text.find('\n')));  // the trend lines
}

TEST_CASE("the settings a part carries change with the scene and the config, not their paths",
          "[campaign][shard]") {
  const Campaign campaign;
  const auto fit_toml = campaign.dir / "fit.toml";
  WriteText(fit_toml, "[fit]\nscan = 16\n");
  const auto settings = [&](const driveline::Scene& scene, const std::string& config) {
    return CampaignSettings(scene, LoadCampaignManifest(campaign.manifest_path, config, ""));
  };
  const std::string base = settings(campaign.scene, fit_toml.string());
  CHECK(base.size() == 16);
  CHECK(base.find_first_not_of("0123456789abcdef") == std::string::npos);
  CHECK(settings(campaign.scene, fit_toml.string()) == base);
  // The same file by another path: the same settings.
  CHECK(settings(campaign.scene, (campaign.dir / "." / "fit.toml").string()) == base);
  // No config (the default fit), another config text, a damping one ulp off, a torque knot moved.
  CHECK(settings(campaign.scene, "") != base);
  WriteText(campaign.dir / "fit2.toml", "[fit]\nscan = 17\n");
  CHECK(settings(campaign.scene, (campaign.dir / "fit2.toml").string()) != base);
  driveline::Scene changed = campaign.scene;
  changed.links[0].damping_Nms_per_rad =
      std::nextafter(changed.links[0].damping_Nms_per_rad, 1e300);
  CHECK(settings(changed, fit_toml.string()) != base);
  changed = campaign.scene;
  changed.torques[0].times_s.back() += 1e-6;
  CHECK(settings(changed, fit_toml.string()) != base);
}

TEST_CASE("a bad --shard value exits 2 naming the option and writes nothing",
          "[campaign][shard][bad_input]") {
  const Campaign campaign;
  const auto out = campaign.dir / "out";
  std::filesystem::create_directories(out);
  for (const char* bad : {"0/2", "3/2", "1/0", "2", "a/b", "1/2/3", "-1/2", "1/", "/2", "1.5/2"}) {
    INFO(bad);
    const auto result = RunMillkit(campaign.Cli("--shard '" + std::string(bad) + "' --out '" +
                                                (out / "part.csv").string() + "'"));
    CHECK(result.exit_code == 2);
    CHECK_THAT(result.stderr_text, Contains("option --shard: '" + std::string(bad) + "'"));
  }
  const auto with_trend =
      RunMillkit(campaign.Cli("--shard 1/2 --out '" + (out / "part.csv").string() + "' --trend '" +
                              (out / "trend.csv").string() + "'"));
  CHECK(with_trend.exit_code == 2);
  CHECK_THAT(with_trend.stderr_text, Contains("option --trend: not with --shard"));
  CHECK(std::filesystem::is_empty(out));
}

TEST_CASE("bad --merge parts exit 2 naming the part and its line, and write nothing",
          "[campaign][shard][bad_input]") {
  // Records that do not exist: every fit fails at once, so the parts are quick to make.
  const Campaign campaign;
  const std::string manifest =
      "file,time,stand\nrecords/x0.csv,2026-01-05,F1\nrecords/x1.csv,2026-01-06,F1\n"
      "records/x2.csv,2026-01-07,F1\n";
  WriteText(campaign.manifest_path, manifest);
  const auto parts = campaign.dir / "parts";
  std::filesystem::create_directories(parts);
  const auto part = [&](const std::string& name) { return (parts / name).string(); };
  for (const char* shard : {"1/2", "2/2", "2/3"}) {
    const std::string name = std::string("p") + shard[0] + shard[2] + ".csv";
    const auto made =
        RunMillkit(campaign.Cli("--shard " + std::string(shard) + " --out '" + part(name) + "'"));
    INFO(made.stderr_text);
    REQUIRE(made.exit_code == 3);  // its fits failed: rows, not a failure of the run
  }
  // A part of another manifest (another file on line 3), a part whose number is not one, a file
  // that is not a part.
  std::string other = ReadText(part("p22.csv"));
  const std::string x1 = "\"records/x1.csv\"";
  REQUIRE(other.find(x1) != std::string::npos);
  WriteText(part("other.csv"), other.replace(other.find(x1), x1.size(), "\"records/y1.csv\""));
  std::string garbled = ReadText(part("p22.csv"));
  const auto last = garbled.rfind(",,,,");
  REQUIRE(last != std::string::npos);
  WriteText(part("garbled.csv"), garbled.replace(last, 4, ",\"gap\",\"rad\",1e-3,abc"));
  WriteText(part("table.csv"), "file,time,stand\n");
  // A part without its settings line, and one fitted after the scene changed (another damping
  // start): the merge cannot tell what its numbers were fitted with.
  std::string unsettled = ReadText(part("p22.csv"));
  const auto settings_line = unsettled.find("# settings ");
  REQUIRE(settings_line != std::string::npos);
  WriteText(
      part("unsettled.csv"),
      unsettled.erase(settings_line, unsettled.find('\n', settings_line) + 1 - settings_line));
  std::string scene_text = ReadText(campaign.scene_path);
  const std::string damping = "damping = 5000.0";
  REQUIRE(scene_text.find(damping) != std::string::npos);
  WriteText(campaign.scene_path,
            std::string(scene_text)
                .replace(scene_text.find(damping), damping.size(), "damping = 5200.0"));
  REQUIRE(RunMillkit(campaign.Cli("--shard 2/2 --out '" + part("changed.csv") + "'")).exit_code ==
          3);
  WriteText(campaign.scene_path, scene_text);
  struct Case {
    std::vector<std::string> parts;
    std::string message;
  };
  const std::vector<Case> cases = {
      {{"p12.csv"}, "manifest.csv: line 3 ('records/x1.csv', fit 1) is in no part"},
      {{"p12.csv", "p22.csv", "p12.csv"}, "is already in"},
      {{"p12.csv", "other.csv"}, "other.csv: line 4: fit 1, manifest line 3"},
      {{"p12.csv", "garbled.csv"}, "garbled.csv: line 4, column 'standard_error': 'abc' is not a"},
      {{"p12.csv", "p23.csv"}, "p23.csv: line 4, column 'shard': a part of 3 shards, but"},
      {{"p12.csv", "unsettled.csv"}, "unsettled.csv: no '# settings' line before the header"},
      {{"p12.csv", "changed.csv"}, "changed.csv: line 2: fitted with other settings ("},
      {{"table.csv"}, "table.csv: line 1: not a campaign part"},
      {{"p12.csv", "missing.csv"}, "option --merge: '"},
  };
  const auto out = campaign.dir / "out";
  std::filesystem::create_directories(out);
  for (const auto& c : cases) {
    std::string list;
    for (const auto& p : c.parts) list += " '" + part(p) + "'";
    INFO(list);
    const auto result =
        RunMillkit(campaign.Cli("--merge" + list + " --out '" + (out / "campaign.csv").string() +
                                "' --trend '" + (out / "trend.csv").string() + "'"));
    CHECK(result.exit_code == 2);
    CHECK_THAT(result.stderr_text, Contains(c.message));
    CHECK(std::filesystem::is_empty(out));
  }
  // The complete set merges (every fit failed: exit 3, every file written).
  const auto good =
      RunMillkit(campaign.Cli("--merge '" + part("p12.csv") + "' '" + part("p22.csv") +
                              "' --out '" + (out / "campaign.csv").string() + "'"));
  CHECK(good.exit_code == 3);
  CHECK_THAT(ReadText(out / "campaign.csv"), Contains("\"records/x2.csv\",\"2026-01-07\""));
}

#if MILLKIT_WITH_MPI
TEST_CASE("mpirun -np 2 writes the same campaign table, trend and plots as a serial run",
          "[campaign][cli][mpi]") {
  const Campaign campaign(kGoneRow);
  const Outputs serial = MakeOutputs(campaign, "serial");
  REQUIRE(RunMillkit(campaign.Cli(serial.Options())).exit_code == 3);
  const Outputs mpi = MakeOutputs(campaign, "mpi");
  const std::string root = geteuid() == 0 ? " --allow-run-as-root" : "";
  const int code = Shell(campaign.dir, "mpirun -np 2 --oversubscribe" + root +
                                           " '" MILLKIT_BINARY "' " + campaign.Cli(mpi.Options()));
  INFO(ReadText(campaign.dir / "stderr"));
  CHECK(code == 3);  // the gone record's row: exit 3 from rank 0, as the serial run
  mpi.RequireSame(serial);
  CHECK_THAT(ReadText(campaign.dir / "stdout"), Contains("2 MPI ranks"));
}

TEST_CASE("a rank whose inputs fail stops every rank: no hang, no output",
          "[campaign][cli][mpi][bad_input]") {
  // Two programs in one job (MPMD): rank 1 gets a --threads it refuses, rank 0 good inputs. Rank 0
  // must not wait for rank 1 in the gather; `timeout` turns a hang into exit 124.
  const Campaign campaign;
  const Outputs outputs = MakeOutputs(campaign, "out");
  const std::string root = geteuid() == 0 ? " --allow-run-as-root" : "";
  const std::string program = " '" MILLKIT_BINARY "' " + campaign.Cli(outputs.Options());
  const int code = Shell(campaign.dir, "timeout 120 mpirun --oversubscribe" + root + " -np 1" +
                                           program + " : -np 1" + program + " --threads 0");
  const std::string stderr_text = ReadText(campaign.dir / "stderr");
  INFO(stderr_text);
  CHECK(code != 0);
  CHECK(code != 124);
  CHECK_THAT(stderr_text, Contains("option --threads: must lie in [1, 256] (got 0)"));
  CHECK_THAT(stderr_text, Contains("another MPI rank failed reading the campaign's inputs"));
  CHECK(std::filesystem::is_empty(outputs.dir));
}
#else
TEST_CASE("a millkit built without MPI refuses a campaign as several mpirun ranks",
          "[campaign][cli][mpi][bad_input]") {
  const Campaign campaign;
  const Outputs outputs = MakeOutputs(campaign, "out");
  const int code = Shell(campaign.dir, "OMPI_COMM_WORLD_SIZE=2 '" MILLKIT_BINARY "' " +
                                           campaign.Cli(outputs.Options()));
  CHECK(code == 2);
  CHECK_THAT(ReadText(campaign.dir / "stderr"), Contains("built without MPI"));
  CHECK(std::filesystem::is_empty(outputs.dir));
}
#endif

}  // namespace millkit::identify
