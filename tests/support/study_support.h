// Test support for the studies (sweeps, coupling optimisation): the bundled five-mass scene,
// loaded once, and the message of an expected InputError.
#pragma once

#include <string>

#include "millkit/driveline/scene.h"
#include "millkit/io/input_error.h"
#include "support/run_cli.h"

namespace millkit::testing {

inline const driveline::Scene& Mill5Scene() {
  static const driveline::Scene scene =
      driveline::LoadScene(SourcePath("datasets/scenes/mill5_bite.toml"));
  return scene;
}

// Appends mass `mass` (inertia J) joined to mass `from` by a copy of the scene's first link
// named `link` (from → new mass).
inline void AppendMass(driveline::Scene* scene, const std::string& mass, double inertia,
                       const std::string& link, int from) {
  scene->masses.push_back({mass, inertia});
  driveline::Link added = scene->links.front();
  added.name = link;
  added.from = from;
  added.to = static_cast<int>(scene->masses.size()) - 1;
  scene->links.push_back(added);
}

// Writes `text` to a scratch file named `file_name`, calls load(path) and returns the message
// of the InputError it throws; "" when it throws none.
template <class Load>
std::string InputErrorOfFile(const std::string& file_name, const std::string& text, Load&& load) {
  ScratchDir dir;
  WriteText(dir / file_name, text);
  try {
    load((dir / file_name).string());
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace millkit::testing
