// libFuzzer harness: MATLAB records (LoadOscillogram on a .mat file, which reads it through
// libmatio in identify/mat_record.cpp, after MillKit's structure check, identify/mat_prescan.h).
// The input is written to a temporary record.mat. Seeds: tests/fuzz/corpus/mat_record_fuzz (MAT
// v5: top-level vectors, and a compressed struct, written by tests/fuzz/make_mat_seeds.py; and
// found_oom_*.mat, damaged files for which libmatio asked for 2-8 GB before the check refused
// them). libmatio is Debian's build, not instrumented: libFuzzer sees the coverage of MillKit's
// reader and check only, and ASan checks libmatio's heap use through its allocator, not its every
// access.
#include "fuzz/fuzz_input.h"
#include "millkit/identify/oscillogram.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = millkit::fuzz::WriteInput(data, size, "record.mat");
  return millkit::fuzz::Outcome([&] { millkit::identify::LoadOscillogram(path); });
}
