// The check every input file passes before it is read, so that a path that cannot be one is told
// apart from a file whose contents are wrong.
#pragma once

#include <filesystem>
#include <string>

namespace millkit {

// Throws InputError naming the path and why it cannot be read: not found, a directory, a loop of
// links, a path that cannot be looked up. Regular files, FIFOs and character devices (a pipe,
// /dev/stdin) pass; a symlink is followed. The message starts with `name` (default: the path).
void CheckInputFile(const std::filesystem::path& path, const std::string& name = {});

}  // namespace millkit
