// Headless Chromium (Debian's chromium, installed by scripts/setup) for the tests of pages: the
// HTML report and the live page.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

namespace objscan::testing {

/// The chromium program on PATH, or empty.
std::string findChromium();

/// A file:// URL of an absolute path, every byte but unreserved ones and '/' percent-encoded.
std::string fileUrl(const std::filesystem::path& path);

/// The DOM of the page at `url` after it loaded in headless Chromium and its scripts ran for
/// `virtual_time_ms` of the page's virtual time (which stands still while a request is open, so a
/// page that polls a server follows it in real time), as Chromium serialises it. Fails the test
/// when Chromium is missing, does not run, or takes more than `timeout_s`.
std::string domInChromium(const std::string& url, int virtual_time_ms = 5000, int timeout_s = 60);

}  // namespace objscan::testing

#include <sys/types.h>

#include <memory>

#include <nlohmann/json.hpp>

#include "test_support.h"

namespace objscan::testing {

/// A headless Chromium page a test drives as a person would: it loads a URL, clicks and types
/// through the browser's own input events, and reads the page by running expressions in it.
/// Chromium is spoken to over the DevTools protocol on a pipe (--remote-debugging-pipe: JSON
/// messages ended by a NUL byte on file descriptors 3 and 4), so no port and no WebSocket
/// library are needed. WebGL runs on SwiftShader (software). Every call fails the test (and
/// returns empty) when the browser does not answer within its timeout.
class ChromiumPage {
 public:
  ChromiumPage(int width = 1280, int height = 800);
  ~ChromiumPage();  ///< closes the browser
  ChromiumPage(const ChromiumPage&) = delete;
  ChromiumPage& operator=(const ChromiumPage&) = delete;

  /// False when Chromium could not be started (the test has failed then).
  bool ok() const { return session_.size() > 0; }
  /// Loads `url` and waits for its load event.
  void navigate(const std::string& url, double timeout_s = 30);
  /// The value of a JavaScript expression in the page (a promise is awaited); null after an
  /// exception, which fails the test.
  nlohmann::json evaluate(const std::string& expression, double timeout_s = 30);
  /// Waits until `expression` is truthy; false (not a failure by itself) after `timeout_s`.
  bool waitFor(const std::string& expression, double timeout_s);
  /// A left click at page coordinates (CSS pixels): mouse moved, pressed and released there.
  void click(double x, double y);
  /// A key pressed and released, as the keyboard sends it: `key` is e.g. "y", " " or "ArrowDown".
  void key(const std::string& key);
  /// What the page logged to the console and its uncaught exceptions, for failure messages.
  const std::string& console() const { return console_; }

 private:
  nlohmann::json command(const std::string& method, const nlohmann::json& params,
                         bool in_page, double timeout_s = 30);
  /// Reads messages until one arrives for which `done` is true, or the time is up.
  bool readUntil(const std::function<bool(const nlohmann::json&)>& done, double timeout_s);
  void handleEvent(const nlohmann::json& message);

  pid_t pid_ = -1;
  int to_browser_ = -1, from_browser_ = -1;
  std::string buffer_, session_, console_;
  int next_id_ = 1;
  bool loaded_ = false;
  std::unique_ptr<TempDir> home_;
};

}  // namespace objscan::testing
