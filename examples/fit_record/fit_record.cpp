// Fit a drive line's parameters to a measured record (torque oscillogram), what
// `millkit identify` does without writing files.
//
//   fit_record SCENE.toml RECORD.csv FIT.toml
// e.g. the bundled scene datasets/scenes/mill5_bite.toml, record
// datasets/records/mill5_two_spindles.csv and fit datasets/records/mill5_two_spindles.fit.toml.
//
// Prints each fitted parameter with its standard error and the fit's verdict. Self-check: the fit
// succeeds with verdict "ok" (the record fits the scene within its noise, the answer is unique);
// otherwise exit 3 (1 when the fit failed). Bad input exits 2.
#include <cstdio>
#include <exception>
#include <iostream>

#include "millkit/driveline/scene.h"
#include "millkit/identify/fit.h"
#include "millkit/identify/fit_config.h"
#include "millkit/identify/oscillogram.h"
#include "millkit/io/input_error.h"

namespace dl = millkit::driveline;
namespace id = millkit::identify;

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: fit_record SCENE.toml RECORD.csv FIT.toml\n";
    return 2;
  }
  try {
    dl::Scene scene = dl::LoadScene(argv[1]);
    const id::Oscillogram record = id::LoadOscillogram(argv[2]);
    const id::FitConfig config = id::LoadFitConfig(argv[3], record, scene);
    id::ApplySetValues(config, &scene);  // [set]: known values, not fitted
    const id::FitResult result = id::Fit(scene, record, config, id::FitOptions{});
    std::cout << result.summary.BriefReport() << "\n";
    if (!result.summary.success) {
      std::cerr << "fit_record: the fit failed: " << result.summary.message << "\n";
      return 1;
    }
    std::printf("%-26s %14s %12s %s\n", "parameter", "value", "std. error", "unit");
    for (const id::ParameterEstimate& p : result.parameters) {
      std::printf("%-26s %14.6g %12.3g %s%s\n", p.name.c_str(), p.value, p.standard_error,
                  p.unit.c_str(), p.identifiable ? "" : "  (not identifiable)");
    }
    std::cout << "verdict: " << result.summary.verdict << "\n";
    for (const auto& warning : result.summary.warnings) std::cerr << "warning: " << warning << "\n";
    return result.summary.verdict == "ok" ? 0 : 3;
  } catch (const millkit::InputError& e) {
    std::cerr << "fit_record: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "fit_record: " << e.what() << "\n";
    return 1;
  }
}
