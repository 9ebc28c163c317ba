// libFuzzer harness: the leveller's CSVs as `millkit leveller` reads them: angles (beta1_deg,
// beta2_deg: forward map of the default linkage for rows in the working range), targets (y1_mm,
// y2_mm: closed-form inverse) and strip lists (ReadStripCases,
// include/millkit/leveller/setpoint_table.h). Seeds: datasets/leveller/*.csv.
#include "fuzz/fuzz_input.h"
#include "millkit/io/csv.h"
#include "millkit/leveller/leveller_config.h"
#include "millkit/leveller/linkage.h"
#include "millkit/leveller/setpoint_table.h"

using namespace millkit;
using namespace millkit::leveller;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const LevellerConfig config = DefaultLevellerConfig();
  static const Linkage linkage(config.linkage);
  const std::string text = fuzz::Text(data, size);
  return fuzz::Outcome([&] {
    const CsvTable table = ParseCsv(text, "fuzz.csv");
    if (table.HasColumn("beta1_deg") && table.HasColumn("beta2_deg")) {
      const int c1 = table.Column("beta1_deg");
      const int c2 = table.Column("beta2_deg");
      const auto& geo = config.linkage;
      for (const auto& row : table.rows) {
        const double b1 = row[c1];
        const double b2 = row[c2];
        if (b1 < geo.beta_min_deg || b1 > geo.beta_max_deg || b2 < geo.beta_min_deg ||
            b2 > geo.beta_max_deg) {
          continue;  // the CLI refuses these with an InputError
        }
        Intermesh<double> y;
        linkage.Forward(b1, b2, &y);
      }
    }
    if (table.HasColumn("y1_mm") && table.HasColumn("y2_mm")) {
      const int c1 = table.Column("y1_mm");
      const int c2 = table.Column("y2_mm");
      for (const auto& row : table.rows) linkage.InverseClosedForm(row[c1], row[c2]);
    }
    if (table.HasColumn("yield_mpa")) ReadStripCases(table);
  });
}
