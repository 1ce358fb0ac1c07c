#include "background_process.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <stdexcept>
#include <thread>

#include "objscan/core/clock.h"

extern char** environ;

namespace objscan::testing {

BackgroundProcess::BackgroundProcess(const std::vector<std::string>& argv) {
  int out_pipe[2];
  if (::pipe2(out_pipe, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out_pipe[1], STDOUT_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, (dir_ / "stderr").c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const int error = posix_spawn(&pid_, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(out_pipe[1]);
  out_fd_ = out_pipe[0];
  if (error != 0) {
    ::close(out_fd_);
    throw std::runtime_error("cannot start " + argv.at(0));
  }
}

BackgroundProcess::~BackgroundProcess() {
  if (running()) {
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
  if (out_fd_ >= 0) ::close(out_fd_);
}

bool BackgroundProcess::readSome(int timeout_ms) {
  pollfd p{out_fd_, POLLIN, 0};
  if (::poll(&p, 1, timeout_ms) <= 0) return true;
  char buffer[4096];
  const ssize_t n = ::read(out_fd_, buffer, sizeof buffer);
  if (n <= 0) return false;
  out_.append(buffer, static_cast<std::size_t>(n));
  return true;
}

std::string BackgroundProcess::waitForLine(const std::string& prefix, double timeout_s) {
  const auto start = SteadyClock::now();
  for (;;) {
    std::size_t at = 0;
    while (at < out_.size()) {
      const std::size_t end = out_.find('\n', at);
      if (end == std::string::npos) break;
      if (out_.compare(at, prefix.size(), prefix) == 0) return out_.substr(at, end - at);
      at = end + 1;
    }
    if (secondsSince(start) > timeout_s || !readSome(100)) return "";
  }
}

void BackgroundProcess::signal(int signal_number) {
  if (running()) ::kill(pid_, signal_number);
}

bool BackgroundProcess::running() {
  if (status_ >= 0) return false;
  int status = 0;
  if (::waitpid(pid_, &status, WNOHANG) != pid_) return true;
  status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return false;
}

int BackgroundProcess::wait(double timeout_s) {
  const auto start = SteadyClock::now();
  while (running()) {
    if (secondsSince(start) > timeout_s) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
      status_ = 128 + SIGKILL;
      return -1;
    }
    readSome(50);
  }
  while (readSome(0)) {
    pollfd p{out_fd_, POLLIN, 0};
    if (::poll(&p, 1, 0) <= 0) break;
  }
  return status_;
}

std::string BackgroundProcess::err() const { return readBytes(dir_ / "stderr"); }

}  // namespace objscan::testing
