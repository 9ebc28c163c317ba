// libFuzzer harness: scene TOML (LoadScene, include/millkit/driveline/scene.h). Seeds:
// datasets/scenes/*.toml; drive_pi.toml's load table is copied beside the input, so that the
// seed parses whole.
#include "fuzz/fuzz_input.h"
#include "millkit/driveline/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool copied =
      std::filesystem::copy_file(millkit::fuzz::DatasetPath("scenes/drive_pi_load.csv"),
                                 millkit::fuzz::InputDir() / "drive_pi_load.csv",
                                 std::filesystem::copy_options::overwrite_existing);
  (void)copied;
  const auto path = millkit::fuzz::WriteInput(data, size, "scene.toml");
  return millkit::fuzz::Outcome([&] { millkit::driveline::LoadScene(path.string()); });
}
