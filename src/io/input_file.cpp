#include "millkit/io/input_file.h"

#include <system_error>

#include "millkit/io/input_error.h"

namespace millkit {

void CheckInputFile(const std::filesystem::path& path, const std::string& name) {
  const std::string what = name.empty() ? path.string() : name;
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (status.type() == std::filesystem::file_type::not_found) {
    throw InputError(what + ": file not found");
  }
  if (error) throw InputError(what + ": cannot be read (" + error.message() + ")");
  if (std::filesystem::is_directory(status)) {
    throw InputError(what + ": is a directory, not a file");
  }
}

}  // namespace millkit
