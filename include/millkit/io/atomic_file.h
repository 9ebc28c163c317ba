// Output files written atomically: the content goes to a temporary file beside the target and is
// renamed over it only on Commit(). A writer destroyed without Commit() removes the temporary, so
// a failed run leaves no partial output behind; SIGINT, SIGTERM and SIGHUP remove it too. An
// existing symlink is written through; an existing device, FIFO, socket or directory is refused
// (millkit/io/output_files.h has the whole protocol).
#pragma once

#include <filesystem>
#include <fstream>
#include <string>

namespace millkit {

class AtomicFile {
 public:
  // Throws InputError when the directory of `path` cannot be written.
  explicit AtomicFile(std::filesystem::path path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ostream& stream() { return stream_; }
  // Flushes and renames the temporary onto the target. Throws InputError on an I/O failure.
  void Commit();

 private:
  std::filesystem::path path_;
  std::filesystem::path target_;  // path_ with a symlink resolved
  std::filesystem::path temp_path_;
  std::ofstream stream_;
  bool committed_ = false;
};

// Writes `content` to `path` atomically.
void WriteFileAtomically(const std::filesystem::path& path, const std::string& content);

}  // namespace millkit
