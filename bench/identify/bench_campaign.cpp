// A campaign on one and on several MPI ranks (issue 15 item 4). Not a test: it times.
//
// Synthetic records of the two-mass line of tests/identify/campaign_test.cpp (spindle 5e6 N·m/rad,
// a 10 mrad gap in the prior; each record 2 kHz, 1 % noise, 12-bit, gain and offset off) whose
// gap wears by 1e-4 rad a day, one record a day on stand F1, are written with their manifest to a
// scratch directory. Then `millkit identify --campaign` runs once alone and once under
// `mpirun -np R` (R ranks, --threads 1 each, unless --threads), both timed from the outside
// (process start to exit: reading, fitting, gathering, writing). Reported: wall times, fits per
// second, the speed-up and the parallel efficiency T1 / (R · TR). The two runs' table and trend
// must be byte for byte the same, and every fit ok: otherwise exit 1.
//
// Usage: bench_campaign [--records N (1000)] [--ranks R (2)] [--threads T (1)] [--keep]
// Needs a millkit built with MPI (MILLKIT_WITH_MPI) and mpirun on the PATH. --keep leaves the
// scratch directory (its path is printed).
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "identify/campaign_line.h"
#include "millkit/driveline/scene.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/identify/record_generator.h"
#include "millkit/io/atomic_file.h"

using namespace millkit;
using namespace millkit::identify;

namespace {

// The line of tests/identify/campaign_test.cpp (identify/campaign_line.h).
constexpr const char* kScene = kCampaignLineScene;
// One record a day; after 100 days the wear starts again (a new spindle every 100 days keeps the
// gap within the prior's reach for any --records).
constexpr int kDaysPerSpindle = 100;

std::string RecordCsv(const driveline::Scene& prior, int day, unsigned long seed) {
  return CampaignLineRecordCsv(
      prior, kCampaignGapAtDay0_rad + kCampaignWearPerDay_rad * (day % kDaysPerSpindle), seed);
}

// YYYY-MM-DD of 2026-01-01 plus `day` days.
std::string Date(int day) {
  const std::time_t t = 1767225600 + static_cast<std::time_t>(day) * 86400;  // 2026-01-01Z
  char text[16];
  std::strftime(text, sizeof text, "%Y-%m-%d", std::gmtime(&t));
  return text;
}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Runs a shell command; its exit code and wall time.
int Timed(const std::string& command, double* seconds) {
  const auto start = std::chrono::steady_clock::now();
  const int status = std::system(command.c_str());
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

int main(int argc, char** argv) {
  int records = 1000, ranks = 2, threads = 1;
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--records" && i + 1 < argc) {
      records = std::atoi(argv[++i]);
    } else if (arg == "--ranks" && i + 1 < argc) {
      ranks = std::atoi(argv[++i]);
    } else if (arg == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (arg == "--keep") {
      keep = true;
    } else {
      std::fprintf(stderr,
                   "usage: bench_campaign [--records N] [--ranks R] [--threads T] [--keep]\n");
      return 2;
    }
  }
  if (records < 1 || ranks < 2 || threads < 1) {
    std::fprintf(stderr, "bench_campaign: --records ≥ 1, --ranks ≥ 2, --threads ≥ 1\n");
    return 2;
  }
  std::random_device device;
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("millkit_bench_campaign_" + std::to_string(device()));
  std::filesystem::create_directories(dir / "records");
  const std::string scene_path = (dir / "scene.toml").string();
  WriteFileAtomically(scene_path, kScene);
  const driveline::Scene scene = driveline::LoadScene(scene_path);

  const auto made = std::chrono::steady_clock::now();
  std::string manifest = "file,time,stand\n";
  for (int k = 0; k < records; ++k) {
    const std::string file = "records/r" + std::to_string(k) + ".csv";
    WriteFileAtomically(dir / file, RecordCsv(scene, k, 1000 + k));
    manifest += file + "," + Date(k) + ",F1\n";
  }
  WriteFileAtomically(dir / "manifest.csv", manifest);
  std::printf("%d synthetic records written in %.1f s to %s\n", records,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - made).count(),
              dir.c_str());

  const auto command = [&](const std::string& name) {
    return "'" MILLKIT_BINARY "' identify '" + scene_path + "' --campaign '" +
           (dir / "manifest.csv").string() + "' --quiet --threads " + std::to_string(threads) +
           " --out '" + (dir / (name + ".csv")).string() + "' --trend '" +
           (dir / (name + "_trend.csv")).string() + "' >'" + (dir / (name + ".log")).string() +
           "' 2>&1";
  };
  double one_s = 0.0, many_s = 0.0;
  const int one_code = Timed(command("one"), &one_s);
  const std::string root = geteuid() == 0 ? " --allow-run-as-root" : "";
  const int many_code = Timed(
      "mpirun -np " + std::to_string(ranks) + " --oversubscribe" + root + " " + command("ranks"),
      &many_s);
  const bool same = ReadFile(dir / "one.csv") == ReadFile(dir / "ranks.csv") &&
                    ReadFile(dir / "one_trend.csv") == ReadFile(dir / "ranks_trend.csv") &&
                    !ReadFile(dir / "one.csv").empty();
  std::printf("1 rank:  %8.1f s  %6.2f fits/s  (exit %d)\n", one_s, records / one_s, one_code);
  std::printf("%d ranks: %8.1f s  %6.2f fits/s  (exit %d)\n", ranks, many_s, records / many_s,
              many_code);
  std::printf(
      "speed-up %.2f on %d ranks, parallel efficiency %.0f %% (threads per rank: %d, "
      "%ld cores, load average at the end: see uptime)\n",
      one_s / many_s, ranks, 100.0 * one_s / (ranks * many_s), threads,
      sysconf(_SC_NPROCESSORS_ONLN));
  std::printf("outputs of the two runs byte for byte the same: %s\n", same ? "yes" : "NO");
  const bool ok = same && one_code == 0 && many_code == 0;
  if (!ok) std::printf("logs: %s/one.log, %s/ranks.log\n", dir.c_str(), dir.c_str());
  if (!keep && ok) std::filesystem::remove_all(dir);
  return ok ? 0 : 1;
}
