#include "io/atomic_file.h"

#include <unistd.h>

#include <system_error>

#include "io/input_error.h"

namespace millkit {

AtomicFile::AtomicFile(std::filesystem::path path) : path_(std::move(path)) {
  temp_path_ = path_;
  temp_path_ += ".tmp." + std::to_string(::getpid());
  stream_.open(temp_path_, std::ios::out | std::ios::trunc);
  if (!stream_) {
    throw InputError(path_.string() + ": cannot open for writing (does the directory exist?)");
  }
  stream_.precision(17);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    stream_.close();
    std::error_code ignored;
    std::filesystem::remove(temp_path_, ignored);
  }
}

void AtomicFile::Commit() {
  stream_.flush();
  const bool ok = static_cast<bool>(stream_);
  stream_.close();
  if (!ok) throw InputError(path_.string() + ": write failed");
  std::error_code error;
  std::filesystem::rename(temp_path_, path_, error);
  if (error) throw InputError(path_.string() + ": cannot replace file: " + error.message());
  committed_ = true;
}

void WriteFileAtomically(const std::filesystem::path& path, const std::string& content) {
  AtomicFile file(path);
  file.stream() << content;
  file.Commit();
}

}  // namespace millkit
