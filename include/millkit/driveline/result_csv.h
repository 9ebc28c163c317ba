// The result CSV of `millkit simulate` (docs/simulate.md#the-result-csv): a header `time,<columns>`
// and one row per kept output sample, every number in the shortest text that reads back to the
// same double. The writer takes samples as a run produces them (SimulationOptions::sample_sink),
// so a long run is streamed to its file and holds no samples in memory.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "millkit/driveline/scene.h"
#include "millkit/driveline/simulation.h"

namespace millkit::driveline {

enum class OutputBlock { kTorque, kSpeed, kTwist };

struct ResultColumn {
  std::string name;  // as in the header: `<link>`, `speed.<mass>`, `twist.<link>`
  OutputBlock block = OutputBlock::kTorque;
  int index = 0;  // scene link or mass
};

// Every output column of the scene in file order: each link's torque, each mass's speed, each
// link's twist.
std::vector<ResultColumn> AllResultColumns(const Scene& scene);

// The columns named in `list`, comma-separated, in the order given (`time` is always written first
// and may be named, once, as the first entry). Throws InputError naming `option`, the name and the
// allowed names for an unknown, empty or repeated name.
std::vector<ResultColumn> SelectResultColumns(const Scene& scene, const std::string& list,
                                              const std::string& option);

class ResultCsvWriter {
 public:
  // Writes the header to `out` (which must outlive the writer); keeps the samples k = 0, every,
  // 2·every, … (every >= 1). `name` names the file in error messages.
  ResultCsvWriter(std::ostream* out, std::string name, std::vector<ResultColumn> columns,
                  int every = 1);
  // Writes the sample's row when it is kept. Throws InputError naming the file when the stream
  // has failed (a full disk), so a long run stops at the first failed write.
  void Write(const OutputSample& sample);
  long rows() const { return rows_; }

 private:
  std::ostream& out_;
  std::string name_;
  std::vector<ResultColumn> columns_;
  int every_;
  long rows_ = 0;
  std::string line_;
};

// Rows a run of `samples` output samples writes keeping every `every`-th: ⌈samples / every⌉.
long KeptRows(long samples, int every);

// Expected size of a result CSV of `rows` data rows of `columns` numbers (time included): the
// header is negligible, a number takes kCsvBytesPerNumber with its separator. Shortest round-trip
// text of a simulated double has 17 significant digits, a sign, a point and often an exponent.
inline constexpr double kCsvBytesPerNumber = 20.0;
double EstimatedCsvBytes(long rows, int columns);

// Outputs above this size are announced before the run starts.
inline constexpr double kLargeOutputBytes = 1e9;
// Empty for an output of at most kLargeOutputBytes, else one warning line (no newline) naming the
// file, its estimated size and the options that make it smaller.
std::string LargeOutputWarning(const std::string& path, double bytes);

}  // namespace millkit::driveline
