// Output paths of a long-running command, checked before the work starts: each file's directory
// must exist and no two outputs may name the same file. The files themselves are written only
// after all work succeeded (WriteFileAtomically), so a failed run leaves nothing behind.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "io/input_error.h"

namespace millkit::cli {

// `outputs`: (option, path) pairs; empty paths (option not given) are skipped.
inline void CheckOutputPaths(const std::vector<std::pair<std::string, std::string>>& outputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const auto& [option, path] = outputs[i];
    if (path.empty()) continue;
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (!parent.empty() && !std::filesystem::is_directory(parent)) {
      throw InputError("option " + option + ": " + path + ": directory " + parent.string() +
                       " does not exist");
    }
    for (size_t j = 0; j < i; ++j) {
      if (!outputs[j].second.empty() && std::filesystem::weakly_canonical(outputs[j].second) ==
                                            std::filesystem::weakly_canonical(path)) {
        throw InputError("options " + outputs[j].first + " and " + option + " name the same file " +
                         path);
      }
    }
  }
}

}  // namespace millkit::cli
