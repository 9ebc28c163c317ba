// Records saved by MATLAB (MAT v5, and v7.3, which is HDF5), read through libmatio: a time vector
// and one vector per channel at the top level of the file, or the fields of one struct that holds
// them. The time vector is the one named `time`, `t`, `Time` or `time_s` (or chosen with
// RecordOptions::time_column), in s; every other real numeric vector of its length is a channel,
// named by its variable (or field) name. Anything else (matrices, vectors of another length, text,
// cells, complex data) is skipped with a note. The user reference is docs/identify.md.
#pragma once

#include <filesystem>

#include "millkit/identify/oscillogram.h"

namespace millkit::identify {

// Throws InputError naming the file, the variable and the rule: not a MAT file, no time vector or
// two of them, two structs that each hold one, a value that is not finite (with its 1-based
// index), a time that does not increase strictly, no channel, fewer than kMinRecordSamples samples.
Oscillogram LoadMatRecord(const std::filesystem::path& path, const RecordOptions& options);

}  // namespace millkit::identify
