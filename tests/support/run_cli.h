// Test support: run the built `millkit` program and capture its exit code and stderr, and make
// scratch directories. Header-only; the test suites get MILLKIT_BINARY and MILLKIT_SOURCE_DIR.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

namespace millkit::testing {

struct CliResult {
  int exit_code = -1;
  std::string stdout_text;
  std::string stderr_text;
};

inline std::string SourcePath(const std::string& relative) {
  return std::string(MILLKIT_SOURCE_DIR) + "/" + relative;
}

inline std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

// A fresh empty directory under the system temp dir, removed on destruction.
class ScratchDir {
 public:
  ScratchDir() {
    std::random_device device;
    path_ = std::filesystem::temp_directory_path() /
            ("millkit_test_" + std::to_string(device()) + std::to_string(device()));
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }
  // Number of entries in the directory (to check that no partial output was left behind).
  int EntryCount() const {
    int n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(path_)) ++n;
    return n;
  }

 private:
  std::filesystem::path path_;
};

// Runs `millkit <arguments>` (arguments are passed to the shell as written).
inline CliResult RunMillkit(const std::string& arguments) {
  ScratchDir capture;
  const auto out_path = capture / "stdout";
  const auto err_path = capture / "stderr";
  const std::string command = std::string("'") + MILLKIT_BINARY + "' " + arguments + " >'" +
                              out_path.string() + "' 2>'" + err_path.string() + "' </dev/null";
  const int status = std::system(command.c_str());
  CliResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.stdout_text = ReadText(out_path);
  result.stderr_text = ReadText(err_path);
  return result;
}

// Runs a shell command line with stdout and stderr to the files `dir`/stdout and `dir`/stderr;
// the exit code (−1 when it did not exit).
inline int Shell(const ScratchDir& dir, const std::string& command) {
  const std::string line =
      command + " >'" + (dir / "stdout").string() + "' 2>'" + (dir / "stderr").string() + "'";
  const int status = std::system(line.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace millkit::testing
