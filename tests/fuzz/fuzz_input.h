// Shared by the parser harnesses (issue 14 item 7). A parser's documented answer to bad input is
// InputError naming the file, key or value; the harnesses count it as a normal outcome. Anything
// else escaping a parser (another exception, which libFuzzer reports as a crash through
// std::terminate), a crash, a sanitizer report or a hang is a finding to fix in the parser.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "millkit/io/input_error.h"

namespace millkit::fuzz {

// Bundled data the harnesses parse against (scene, record): the repository's datasets/.
inline std::string DatasetPath(const std::string& relative) {
  return std::string(MILLKIT_DATASETS_DIR) + "/" + relative;
}

// The input as text.
inline std::string Text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

// This process's own temporary directory (parallel fuzzing jobs do not share it).
inline const std::filesystem::path& InputDir() {
  static const std::filesystem::path dir = [] {
    auto path = std::filesystem::temp_directory_path() /
                ("millkit_fuzz_" + std::to_string(static_cast<long>(getpid())));
    std::filesystem::create_directories(path);
    return path;
  }();
  return dir;
}

// Writes the input to `name` in InputDir() and returns the path, for parsers that read files.
inline std::filesystem::path WriteInput(const std::uint8_t* data, std::size_t size,
                                        const std::string& name) {
  const std::filesystem::path path = InputDir() / name;
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

// Runs `parse`; InputError is a refusal with a named rule, a normal outcome. With
// MILLKIT_FUZZ_VERBOSE set, the harness prints the refusal (to check that a seed parses).
template <class Parse>
int Outcome(Parse&& parse) {
  static const bool verbose = std::getenv("MILLKIT_FUZZ_VERBOSE") != nullptr;
  try {
    parse();
    if (verbose) std::fprintf(stderr, "parsed\n");
  } catch (const InputError& error) {
    if (verbose) std::fprintf(stderr, "InputError: %s\n", error.what());
  }
  return 0;
}

}  // namespace millkit::fuzz
