// A progress line on a terminal stream for a long single-threaded run (issue 13): nothing for the
// first second (short runs print nothing), then the line is rewritten at most twice a second;
// Finish() (or the destructor) ends it with a newline when anything was printed.
#pragma once

#include <chrono>
#include <cstdio>
#include <ostream>
#include <string>

namespace millkit {

class ProgressLine {
 public:
  ProgressLine(std::ostream* out, std::string label)
      : out_(out), label_(std::move(label)), started_(Clock::now()), next_(started_ + kDelay) {}
  ~ProgressLine() { Finish(); }
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  // For a caller polled per sample (millions of times): true when Update would print now, asked
  // of the clock only every 64th call, so the caller can skip building the state text.
  bool Due() {
    if (out_ == nullptr || (++polls_ & 63) != 0) return false;
    return Clock::now() >= next_;
  }
  // Cheap when nothing is due: one clock read.
  void Update(const std::string& state) {
    if (out_ == nullptr) return;
    const auto now = Clock::now();
    if (now < next_) return;
    next_ = now + kInterval;
    const double elapsed = std::chrono::duration<double>(now - started_).count();
    char seconds[32];
    std::snprintf(seconds, sizeof(seconds), "%.1f s", elapsed);
    *out_ << "\r" << label_ << ": " << state << ", " << seconds << "   " << std::flush;
    printed_ = true;
  }
  void Finish() {
    if (printed_ && out_ != nullptr) *out_ << "\n" << std::flush;
    printed_ = false;
  }

 private:
  using Clock = std::chrono::steady_clock;
  static constexpr auto kDelay = std::chrono::seconds(1);
  static constexpr auto kInterval = std::chrono::milliseconds(500);
  std::ostream* out_;
  std::string label_;
  Clock::time_point started_;
  Clock::time_point next_;
  bool printed_ = false;
  unsigned long polls_ = 0;
};

}  // namespace millkit
