// The main() every benchmark shares: run it, and turn an exception into one line on stderr
// ("NAME: what went wrong") and exit status 1.
#pragma once

#include <cstdio>
#include <exception>

namespace objscan::bench {

inline int guardedMain(const char* name, int (*run)(int, char**), int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", name, e.what());
    return 1;
  }
}

}  // namespace objscan::bench
