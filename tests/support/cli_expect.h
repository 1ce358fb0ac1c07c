// Expectations the command-line tests share.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "test_support.h"

namespace objscan::testing {

/// Runs the objscan binary under test (OBJSCAN_EXE, build_paths.h) with `args`.
inline ProcessResult objscan(std::vector<std::string> args) {
  args.insert(args.begin(), OBJSCAN_EXE);
  return runProcess(args);
}

/// One line on stderr starting "objscan: error: " and holding `needle`; nothing on stdout; exit
/// status `code`.
inline void expectOneErrorLine(const ProcessResult& r, int code, const std::string& needle) {
  EXPECT_EQ(r.exit_code, code) << r.err;
  EXPECT_EQ(r.out, "");
  std::size_t errors = 0;
  for (const std::string& l : lines(r.err)) errors += l.rfind("objscan: error: ", 0) == 0 ? 1 : 0;
  EXPECT_EQ(errors, 1u) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
}

}  // namespace objscan::testing
