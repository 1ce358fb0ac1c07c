// A program run in the background while a test talks to it (objscan scan --serve).
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

#include "test_support.h"

namespace objscan::testing {

class BackgroundProcess {
 public:
  /// Starts argv[0] with the arguments, stdout on a pipe this object reads, stderr to a file.
  explicit BackgroundProcess(const std::vector<std::string>& argv);
  /// Kills the program (SIGKILL) if it still runs.
  ~BackgroundProcess();
  BackgroundProcess(const BackgroundProcess&) = delete;
  BackgroundProcess& operator=(const BackgroundProcess&) = delete;

  /// The first line of stdout that starts with `prefix` (without its '\n'), waiting up to
  /// `timeout_s` for it; empty when it did not come (or the program ended first).
  std::string waitForLine(const std::string& prefix, double timeout_s);
  void signal(int signal_number);
  /// The exit status (128 + signal number when killed by one), waiting up to `timeout_s`; -1
  /// after that (the program is then killed).
  int wait(double timeout_s);
  bool running();
  const std::string& out() const { return out_; }  ///< stdout read so far (all of it after wait)
  std::string err() const;                         ///< stderr so far

 private:
  /// Reads what stdout has within `timeout_ms`; false at its end.
  bool readSome(int timeout_ms);
  pid_t pid_ = -1;
  int out_fd_ = -1;
  int status_ = -1;
  std::string out_;
  TempDir dir_;
};

}  // namespace objscan::testing
