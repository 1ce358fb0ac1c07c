#include "browser.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "test_support.h"

namespace objscan::testing {

namespace fs = std::filesystem;

std::string findChromium() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "");
  for (std::string d; std::getline(dirs, d, ':');) {
    const fs::path candidate = fs::path(d.empty() ? "." : d) / "chromium";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

std::string fileUrl(const fs::path& path) {
  std::string url = "file://";
  for (const char c : path.string()) {
    const auto u = static_cast<unsigned char>(c);
    if (std::isalnum(u) || c == '/' || c == '-' || c == '_' || c == '.' || c == '~') {
      url += c;
    } else {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", u);
      url += hex;
    }
  }
  return url;
}

std::string domInChromium(const std::string& url, int virtual_time_ms, int timeout_s) {
  const std::string chromium = findChromium();
  if (chromium.empty()) {
    ADD_FAILURE() << "chromium is not on PATH: run scripts/setup, which installs Debian's "
                     "chromium package for this test";
    return "";
  }
  // Chromium writes its profile and caches into `home`, not into the real home (env(1) replaces
  // HOME; runProcess's extra variables would only add a second one after it).
  TempDir home;
  // --no-sandbox: Chromium refuses to run as root with its sandbox (and containers often lack
  // the user namespaces it needs). coreutils' timeout keeps a hung browser from hanging the suite.
  const ProcessResult r = runProcess(
      {"/usr/bin/timeout", std::to_string(timeout_s), "/usr/bin/env",
       "HOME=" + home.path().string(), "XDG_CONFIG_HOME=" + (home.path() / "config").string(),
       "XDG_CACHE_HOME=" + (home.path() / "cache").string(), chromium, "--headless=new",
       "--no-sandbox", "--disable-gpu", "--no-first-run",
       "--user-data-dir=" + (home.path() / "profile").string(),
       "--virtual-time-budget=" + std::to_string(virtual_time_ms), "--dump-dom", url});
  EXPECT_EQ(r.exit_code, 0) << (r.exit_code == 124 ? "chromium did not finish in time\n" : "")
                            << r.err;
  EXPECT_NE(r.out.find("</body>"), std::string::npos) << "stdout:\n"
                                                      << r.out << "\nstderr:\n"
                                                      << r.err;
  return r.out;
}

}  // namespace objscan::testing
