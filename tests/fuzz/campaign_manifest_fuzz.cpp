// libFuzzer harness: campaign manifest CSV (LoadCampaignManifest, ParseIsoTime;
// include/millkit/identify/campaign.h). Seeds: tests/fuzz/corpus/campaign_manifest_fuzz/.
#include "fuzz/fuzz_input.h"
#include "millkit/identify/campaign.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  millkit::identify::ParseIsoTime(millkit::fuzz::Text(data, size));
  const auto path = millkit::fuzz::WriteInput(data, size, "manifest.csv");
  return millkit::fuzz::Outcome([&] { millkit::identify::LoadCampaignManifest(path, "", ""); });
}
