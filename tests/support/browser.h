// Headless Chromium (Debian's chromium, installed by scripts/setup) for the tests of pages: the
// HTML report and the live page.
#pragma once

#include <filesystem>
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
