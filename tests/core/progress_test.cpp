#include "objscan/core/progress.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "objscan/core/log.h"
#include "test_support.h"

namespace objscan {
namespace {

/// Runs `body` with a ProgressBar writing into a real temporary file and returns what it wrote.
template <class Body>
std::string capture(Body body) {
  std::FILE* f = std::tmpfile();
  body(f);
  std::fflush(f);
  std::rewind(f);
  std::string out;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) out.append(buf, n);
  std::fclose(f);
  return out;
}

TEST(ProgressBar, LinesStylePrintsOneLinePerTenPercentAndAFinalLine) {
  const std::string out = capture([](std::FILE* f) {
    ProgressBar bar("fusing", 200, ProgressBar::Style::kLines, f);
    for (int i = 0; i < 200; ++i) bar.advance();
  });
  const auto ls = testing::lines(out);
  ASSERT_EQ(ls.size(), 11u) << out;  // 0 %, 10 %, ..., 90 %, then the final line
  EXPECT_EQ(ls.front().rfind("fusing:   0% (1/200)", 0), 0u) << ls.front();
  EXPECT_EQ(ls[5].rfind("fusing:  50% (100/200)", 0), 0u) << ls[5];
  EXPECT_EQ(ls.back().rfind("fusing: 100% (200/200) in ", 0), 0u) << ls.back();
  EXPECT_EQ(out.find('\r'), std::string::npos);
}

TEST(ProgressBar, RedrawStyleRewritesOneLineAndEndsWithNewline) {
  const std::string out = capture([](std::FILE* f) {
    ProgressBar bar("meshing", 10, ProgressBar::Style::kRedraw, f);
    bar.advance(3);
    bar.finish();
    bar.finish();  // a second finish prints nothing
  });
  EXPECT_EQ(out.front(), '\r');
  EXPECT_NE(out.find("[#########.....................]  30% (3/10)"), std::string::npos) << out;
  EXPECT_EQ(testing::lines(out).size(), 1u) << "one terminal line, redrawn";
  EXPECT_NE(out.find("meshing:  30% (3/10) in "), std::string::npos);
  EXPECT_EQ(out.back(), '\n');
}

TEST(ProgressBar, AFailedStagePrintsNoCompletionLine) {
  auto failedStage = [](ProgressBar::Style style) {
    return capture([style](std::FILE* f) {
      try {
        ProgressBar bar("decoding", 100, style, f);
        bar.advance(5);
        throw std::runtime_error("bad frame");
      } catch (const std::runtime_error&) {
      }
    });
  };
  const std::string lines_out = failedStage(ProgressBar::Style::kLines);
  EXPECT_EQ(lines_out.find(" in "), std::string::npos) << lines_out;
  const std::string redraw_out = failedStage(ProgressBar::Style::kRedraw);
  // The bar is cleared so the error message that follows starts on a clean line.
  EXPECT_TRUE(redraw_out.ends_with("\r\033[K")) << redraw_out;
  EXPECT_EQ(redraw_out.find(" in "), std::string::npos);
}

TEST(ProgressBar, UnknownTotalShowsCounts) {
  const std::string out = capture([](std::FILE* f) {
    ProgressBar bar("frames", 0, ProgressBar::Style::kLines, f);
    bar.advance(5);
  });
  EXPECT_NE(out.find("frames: 5 in "), std::string::npos) << out;
}

TEST(ProgressBar, QuietLogLevelSilencesIt) {
  log::setLevel(log::Level::kError);
  const std::string out = capture([](std::FILE* f) {
    ProgressBar bar("x", 10, ProgressBar::Style::kLines, f);
    bar.advance(10);
  });
  log::setLevel(log::Level::kInfo);
  EXPECT_EQ(out, "");
}

TEST(ProgressBar, ConcurrentAdvancesAreAllCounted) {
  std::size_t done = 0;
  const std::string out = capture([&](std::FILE* f) {
    ProgressBar bar("parallel", 40000, ProgressBar::Style::kLines, f);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&] {
        for (int i = 0; i < 10000; ++i) bar.advance();
      });
    }
    for (auto& t : threads) t.join();
    done = bar.done();
  });
  EXPECT_EQ(done, 40000u);
  EXPECT_NE(out.find("parallel: 100% (40000/40000) in "), std::string::npos) << out;
}

}  // namespace
}  // namespace objscan
