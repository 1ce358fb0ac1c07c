// peak_memory PROGRAM ARGS...: runs PROGRAM and prints, as its last line on stdout,
// "peak_memory <kB> <seconds> <exit status>" (the kernel's ru_maxrss of that process).
//
// A separate, small program on purpose: Linux carries a process's peak resident set over exec,
// so a child forked from a large process (a benchmark holding a 3-million-vertex mesh) would
// report the parent's size as its own. Forked from this one, the carried-over part is only this
// program's own few megabytes.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: peak_memory PROGRAM [ARGS...]\n");
    return 2;
  }
  std::fflush(stdout);
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid < 0) return 2;
  if (pid == 0) {
    execv(argv[1], argv + 1);
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  if (wait4(pid, &status, 0, &usage) != pid) return 2;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::printf("peak_memory %ld %.3f %d\n", usage.ru_maxrss, seconds, code);
  return 0;
}
