#include "millkit/io/atomic_file.h"

#include <sys/stat.h>
#include <unistd.h>

#include <system_error>

#include "millkit/io/input_error.h"
#include "millkit/io/output_files.h"

namespace millkit {

AtomicFile::AtomicFile(std::filesystem::path path) : path_(std::move(path)) {
  // A symlink is written through: the temporary goes beside its target, which is replaced.
  target_ = ResolvedOutputPath(path_);
  struct stat info {};
  if (::stat(target_.c_str(), &info) == 0 && !S_ISREG(info.st_mode)) {
    throw InputError(path_.string() +
                     ": is not a regular file (a device, FIFO, socket or directory); an output "
                     "must be a new path or a regular file");
  }
  temp_path_ = target_;
  temp_path_ += ".tmp." + std::to_string(::getpid());
  RegisterTemporaryFile(temp_path_);
  stream_.open(temp_path_, std::ios::out | std::ios::trunc);
  if (!stream_) {
    ReleaseTemporaryFile(temp_path_);
    throw InputError(path_.string() + ": cannot open for writing (does the directory exist?)");
  }
  stream_.precision(17);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    stream_.close();
    std::error_code ignored;
    std::filesystem::remove(temp_path_, ignored);
    ReleaseTemporaryFile(temp_path_);
  }
}

void AtomicFile::Commit() {
  stream_.flush();
  const bool ok = static_cast<bool>(stream_);
  stream_.close();
  if (!ok) throw InputError(path_.string() + ": write failed");
  std::error_code error;
  std::filesystem::rename(temp_path_, target_, error);
  if (error) throw InputError(path_.string() + ": cannot replace file: " + error.message());
  committed_ = true;
  ReleaseTemporaryFile(temp_path_);
}

void WriteFileAtomically(const std::filesystem::path& path, const std::string& content) {
  AtomicFile file(path);
  file.stream() << content;
  file.Commit();
}

}  // namespace millkit
