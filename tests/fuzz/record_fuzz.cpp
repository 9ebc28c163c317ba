// libFuzzer harness: record tables, CSV in its dialects and the iba ASCII export
// (ParseOscillogram, include/millkit/identify/oscillogram.h, which uses ParseCsv). Seeds:
// datasets/records/*.csv, datasets/scenes/drive_pi_load.csv, datasets/leveller/*.csv.
#include "fuzz/fuzz_input.h"
#include "millkit/identify/oscillogram.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = millkit::fuzz::Text(data, size);
  return millkit::fuzz::Outcome([&] { millkit::identify::ParseOscillogram(text, "fuzz.csv"); });
}
