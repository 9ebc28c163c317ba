// libFuzzer harness: COMTRADE records (LoadComtrade, include/millkit/identify/comtrade.h). The
// input is the .cfg, a line "#DAT", then the .dat (ASCII or binary); both are written to
// temporary files. Seeds: tests/fuzz/corpus/comtrade_fuzz (an ASCII and a BINARY record of the
// layout tests/identify/comtrade_test.cpp writes).
#include <string_view>

#include "fuzz/fuzz_input.h"
#include "millkit/identify/comtrade.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  constexpr std::string_view kMarker = "\n#DAT\n";
  const std::size_t split = std::min(input.find(kMarker), size);
  const std::size_t dat = std::min(split + kMarker.size(), size);
  const auto cfg = millkit::fuzz::WriteInput(data, split, "record.cfg");
  millkit::fuzz::WriteInput(data + dat, size - dat, "record.dat");
  return millkit::fuzz::Outcome([&] { millkit::identify::LoadComtrade(cfg); });
}
