// The one protocol for the files a command writes (issue 13):
//  1. Outputs are declared and checked before the work (CheckOutputPaths): the directory exists
//     and can be written; the path is not any input (same device and inode, so another name for
//     the same file is caught); it is not an existing directory, device, FIFO or socket; no two
//     outputs are the same file. An existing symlink is written through, link by link: its
//     target is replaced (or made, for a link to a file not made yet), the link stays; a loop of
//     links is refused.
//  2. Each output is written to a temporary file beside its (resolved) target and renamed over it
//     only after the work succeeded (AtomicFile).
//  3. Temporary files are removed on every error, and on SIGINT, SIGTERM and SIGHUP by a signal
//     handler before the signal takes its default action, once a program has installed it
//     (InstallTemporaryFileCleanup: the millkit command line does; a library never installs
//     signal handlers behind its user's back).
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace millkit {

// outputs: (option, path) pairs; inputs: every file the command reads. Empty paths are skipped.
// Throws InputError naming the option, the path and the rule.
void CheckOutputPaths(const std::vector<std::pair<std::string, std::string>>& outputs,
                      const std::vector<std::string>& inputs);

// Where an output is actually written: an existing symlink resolved, link by link, to its final
// target (which need not exist yet); the path itself when it is no symlink or a loop of them.
std::filesystem::path ResolvedOutputPath(const std::filesystem::path& path);

// Installs, once, the handlers that remove registered temporary files on SIGINT, SIGTERM and
// SIGHUP and then re-raise the signal with its default action.
void InstallTemporaryFileCleanup();
// Temporary files the handler removes; AtomicFile registers and releases its own.
void RegisterTemporaryFile(const std::filesystem::path& path);
void ReleaseTemporaryFile(const std::filesystem::path& path);

}  // namespace millkit
