#include "millkit/io/output_files.h"

#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <mutex>

#include "millkit/io/input_error.h"

namespace millkit {
namespace {

// Registered temporary paths, in fixed buffers the signal handler can read without allocating.
constexpr int kMaxTemporaryFiles = 64;
constexpr int kMaxPathBytes = 4096;
char temporary_paths[kMaxTemporaryFiles][kMaxPathBytes];
volatile std::sig_atomic_t temporary_used[kMaxTemporaryFiles];
std::mutex temporary_mutex;

extern "C" void RemoveTemporariesAndReraise(int signal_number) {
  for (int k = 0; k < kMaxTemporaryFiles; ++k) {
    if (temporary_used[k]) ::unlink(temporary_paths[k]);
  }
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

std::string Describe(const std::string& option, const std::string& path) {
  return "option " + option + ": " + path;
}

}  // namespace

std::filesystem::path ResolvedOutputPath(const std::filesystem::path& path) {
  // Link by link, so that a link to a file not made yet is written through as well (the
  // filesystem's canonical forms stop at a dangling link). A loop is left as it is.
  constexpr int kMaxLinks = 40;  // Linux's own limit on links in one lookup
  std::error_code error;
  std::filesystem::path current = path;
  int links = 0;
  for (; links < kMaxLinks; ++links) {
    if (!std::filesystem::is_symlink(std::filesystem::symlink_status(current, error))) break;
    const std::filesystem::path target = std::filesystem::read_symlink(current, error);
    if (error) return path;
    current = target.is_absolute() ? target : current.parent_path() / target;
  }
  if (links == 0 || links == kMaxLinks) return path;
  auto resolved = std::filesystem::weakly_canonical(std::filesystem::absolute(current), error);
  return error ? path : resolved;
}

void CheckOutputPaths(const std::vector<std::pair<std::string, std::string>>& outputs,
                      const std::vector<std::string>& inputs) {
  std::vector<std::pair<dev_t, ino_t>> input_ids;
  for (const auto& input : inputs) {
    struct stat info {};
    if (!input.empty() && ::stat(input.c_str(), &info) == 0) {
      input_ids.emplace_back(info.st_dev, info.st_ino);
    }
  }
  std::vector<std::filesystem::path> resolved;
  for (const auto& [option, path] : outputs) {
    if (path.empty()) {
      resolved.emplace_back();
      continue;
    }
    const std::filesystem::path target = ResolvedOutputPath(path);
    struct stat info {};
    if (::stat(target.c_str(), &info) == 0) {
      if (!S_ISREG(info.st_mode)) {
        const char* kind = S_ISDIR(info.st_mode)                            ? "a directory"
                           : S_ISFIFO(info.st_mode)                         ? "a FIFO"
                           : S_ISSOCK(info.st_mode)                         ? "a socket"
                           : S_ISCHR(info.st_mode) || S_ISBLK(info.st_mode) ? "a device"
                                                                            : "not a regular file";
        throw InputError(Describe(option, path) + " is " + kind +
                         "; an output must be a new path or a regular file");
      }
      for (const auto& [device, inode] : input_ids) {
        if (info.st_dev == device && info.st_ino == inode) {
          throw InputError(Describe(option, path) +
                           " is one of this command's inputs; an output never replaces an input");
        }
      }
    }
    std::filesystem::path directory = target.parent_path();
    if (directory.empty()) directory = ".";
    std::error_code unreadable;
    if (!std::filesystem::is_directory(directory, unreadable)) {
      throw InputError(Describe(option, path) + ": directory " + directory.string() +
                       " does not exist");
    }
    if (::access(directory.c_str(), W_OK | X_OK) != 0) {
      throw InputError(Describe(option, path) + ": directory " + directory.string() +
                       " is not writable");
    }
    // Absolute first: weakly_canonical leaves a relative path whose first component does not
    // exist as it is, so "fit.json" and "./fit.json" would differ until the file exists.
    std::error_code unresolved;
    const auto canonical =
        std::filesystem::weakly_canonical(std::filesystem::absolute(target), unresolved);
    if (unresolved) {
      throw InputError(Describe(option, path) + ": cannot be resolved (" + unresolved.message() +
                       "); an output must be a new path or a regular file");
    }
    for (size_t j = 0; j < resolved.size(); ++j) {
      if (!resolved[j].empty() && resolved[j] == canonical) {
        throw InputError("options " + outputs[j].first + " and " + option + " name the same file " +
                         path);
      }
    }
    resolved.push_back(canonical);
  }
}

void InstallTemporaryFileCleanup() {
  static std::once_flag once;
  std::call_once(once, [] {
    for (const int signal_number : {SIGINT, SIGTERM, SIGHUP}) {
      struct sigaction action {};
      action.sa_handler = RemoveTemporariesAndReraise;
      sigemptyset(&action.sa_mask);
      ::sigaction(signal_number, &action, nullptr);
    }
  });
}

void RegisterTemporaryFile(const std::filesystem::path& path) {
  const std::string text = path.string();
  if (text.size() + 1 > static_cast<size_t>(kMaxPathBytes)) return;
  std::lock_guard<std::mutex> lock(temporary_mutex);
  for (int k = 0; k < kMaxTemporaryFiles; ++k) {
    if (!temporary_used[k]) {
      std::memcpy(temporary_paths[k], text.c_str(), text.size() + 1);
      temporary_used[k] = 1;
      return;
    }
  }
}

void ReleaseTemporaryFile(const std::filesystem::path& path) {
  const std::string text = path.string();
  std::lock_guard<std::mutex> lock(temporary_mutex);
  for (int k = 0; k < kMaxTemporaryFiles; ++k) {
    if (temporary_used[k] && text == temporary_paths[k]) {
      temporary_used[k] = 0;
      return;
    }
  }
}

}  // namespace millkit
