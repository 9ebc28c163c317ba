// Parallel fits (issue 15 item 2): the search's scan, preselection, starts, hops and axis probes
// run on FitOptions::threads workers, and every number of the result is the same for any count.
#include <catch2/catch.hpp>
#include <string>

#include "identify/random_line.h"
#include "millkit/identify/fit.h"
#include "support/run_cli.h"

using namespace millkit;
using namespace millkit::identify;

namespace {

// Bit-for-bit equality of everything a fit reports, except its wall time.
void CheckSameFit(const FitResult& a, const FitResult& b) {
  CHECK(a.summary.success == b.summary.success);
  CHECK(a.summary.verdict == b.summary.verdict);
  CHECK(a.summary.warnings == b.summary.warnings);
  CHECK(a.summary.message == b.summary.message);
  CHECK(a.summary.cost == b.summary.cost);
  CHECK(a.summary.simulations == b.summary.simulations);
  CHECK(a.summary.starts == b.summary.starts);
  CHECK(a.summary.starts_at_best == b.summary.starts_at_best);
  CHECK(a.summary.escalated == b.summary.escalated);
  CHECK(a.summary.iterations == b.summary.iterations);
  REQUIRE(a.parameters.size() == b.parameters.size());
  for (size_t i = 0; i < a.parameters.size(); ++i) {
    INFO(a.parameters[i].name);
    CHECK(a.parameters[i].value == b.parameters[i].value);
    CHECK(a.parameters[i].standard_error == b.parameters[i].standard_error);
  }
  REQUIRE(a.channels.size() == b.channels.size());
  for (size_t c = 0; c < a.channels.size(); ++c) {
    CHECK(a.channels[c].gain == b.channels[c].gain);
    CHECK(a.channels[c].offset == b.channels[c].offset);
  }
  REQUIRE(a.minima.size() == b.minima.size());
  for (size_t m = 0; m < a.minima.size(); ++m) {
    CHECK(a.minima[m].cost == b.minima[m].cost);
    CHECK(a.minima[m].values == b.minima[m].values);
  }
}

}  // namespace

TEST_CASE("parallel fit: random lines give the same result on 1, 2 and 3 threads") {
  // Seeds not used to tune anything.
  for (const unsigned long seed : {4ul, 7ul, 19ul}) {
    INFO("seed " << seed);
    const RandomLineCase line = MakeRandomLineCase(seed);
    FitOptions options;
    options.threads = 1;
    const FitResult serial = Fit(line.prior, line.record, line.config, options);
    REQUIRE(serial.summary.simulations > 0);
    for (const int threads : {2, 3}) {
      INFO(threads << " threads");
      options.threads = threads;
      CheckSameFit(serial, Fit(line.prior, line.record, line.config, options));
    }
  }
}

TEST_CASE(
    "identify --threads 2 and the default write the same JSON as one thread, and --threads 0 "
    "exits 2") {
  using namespace millkit::testing;
  ScratchDir dir;
  const std::string common =
      "identify '" + SourcePath("datasets/scenes/mill5_bite.toml") + "' --data '" +
      SourcePath("datasets/records/mill5_two_spindles.csv") + "' --config '" +
      SourcePath("datasets/records/mill5_two_spindles.fit.toml") + "' --quiet --out ";
  const auto one = RunMillkit(common + "'" + (dir / "one.json").string() + "' --threads 1");
  const auto two = RunMillkit(common + "'" + (dir / "two.json").string() + "' --threads 2");
  const auto cores = RunMillkit(common + "'" + (dir / "cores.json").string() + "'");
  REQUIRE(one.exit_code == two.exit_code);
  REQUIRE(one.exit_code == cores.exit_code);
  std::string a = ReadText(dir / "one.json"), b = ReadText(dir / "two.json");
  // The wall time is the one line that may differ.
  const auto drop_wall = [](std::string text) {
    const auto at = text.find("\"wall_time_s\"");
    if (at != std::string::npos) text.erase(at, text.find('\n', at) - at);
    return text;
  };
  CHECK(drop_wall(a) == drop_wall(b));
  CHECK(drop_wall(a) == drop_wall(ReadText(dir / "cores.json")));
  const auto bad = RunMillkit(common + "'" + (dir / "bad.json").string() + "' --threads 0");
  CHECK(bad.exit_code == 2);
  CHECK_THAT(bad.stderr_text, Catch::Matchers::Contains("--threads"));
  CHECK_FALSE(std::filesystem::exists(dir / "bad.json"));
}
