// COMTRADE records (IEEE C37.111-1999/2013), as iba's extractor and many drive recorders write
// them: a .cfg file describing the channels and a .dat file of samples, ASCII, BINARY (int16),
// BINARY32 (int32) or FLOAT32. Each analog channel becomes a record column named by its channel
// id, its values a·x + b with a and b from the .cfg, its unit the .cfg's (read like a units row:
// N·m, kN·m or MN·m for a fitted channel, see fit_config.h). Digital channels are skipped. Time
// comes from the sample rates when the .cfg gives them (samp > 0), else from each sample's
// timestamp (µs × timemult).
#pragma once

#include <filesystem>

#include "millkit/identify/oscillogram.h"

namespace millkit::identify {

// Reads `cfg` and the .dat beside it (same stem). Throws InputError naming the file and line (or
// byte offset) and the rule for anything malformed: a wrong channel count, an unknown file type,
// a truncated binary file, a time that does not increase strictly.
Oscillogram LoadComtrade(const std::filesystem::path& cfg);

}  // namespace millkit::identify
