// MillKit's own check of a MAT file's structure before libmatio reads it (identify/ internal).
// libmatio trusts the sizes a file declares: a damaged MAT v5 file (dimensions, a name length or a
// compressed variable's size that the bytes do not hold) makes it ask for gigabytes before it
// finds out. The check walks every v5 data element, inflating compressed variables (zlib), and
// refuses one whose declared contents the file cannot hold.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>

namespace millkit::identify {

// The largest variable the check inflates: 1 GiB uncompressed.
inline constexpr std::size_t kMaxInflatedVariableBytes = std::size_t{1} << 30;

enum class MatVersion { kV5, kV73 };

// Checks the file's header and, for MAT v5, every data element. Returns the version; throws
// InputError naming `source`, the byte offset and the rule broken.
MatVersion CheckMatFile(const std::filesystem::path& path, const std::string& source);

// The same on bytes already read (the whole file).
MatVersion CheckMatBytes(std::string_view bytes, const std::string& source);

}  // namespace millkit::identify
