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

// ---- ChromiumPage ------------------------------------------------------------------------------

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <chrono>
#include <cstring>

extern char** environ;

namespace objscan::testing {

using Json = nlohmann::json;

namespace {

double secondsFrom(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

ChromiumPage::ChromiumPage(int width, int height) : home_(std::make_unique<TempDir>()) {
  const std::string chromium = findChromium();
  if (chromium.empty()) {
    ADD_FAILURE() << "chromium is not on PATH: run scripts/setup, which installs Debian's "
                     "chromium package for this test";
    return;
  }
  int in[2], out[2];  // in: test -> browser (its fd 3); out: browser -> test (its fd 4)
  if (pipe2(in, O_CLOEXEC) != 0 || pipe2(out, O_CLOEXEC) != 0) {
    ADD_FAILURE() << "pipe: " << std::strerror(errno);
    return;
  }
  const fs::path home = home_->path();
  std::vector<std::string> args = {
      chromium, "--headless=new", "--no-sandbox", "--no-first-run", "--remote-debugging-pipe",
      // WebGL without a GPU: SwiftShader, which Chromium only uses for WebGL when told to.
      "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
      "--window-size=" + std::to_string(width) + "," + std::to_string(height),
      "--user-data-dir=" + (home / "profile").string(), "about:blank"};
  std::vector<std::string> env = {"HOME=" + home.string(),
                                  "XDG_CONFIG_HOME=" + (home / "config").string(),
                                  "XDG_CACHE_HOME=" + (home / "cache").string()};
  for (char** e = environ; *e; ++e) {
    const std::string_view v = *e;
    if (v.rfind("HOME=", 0) != 0 && v.rfind("XDG_", 0) != 0) env.emplace_back(v);
  }
  std::vector<char*> argv, envp;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  for (std::string& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in[0], 3);
  posix_spawn_file_actions_adddup2(&actions, out[1], 4);
  const std::string log = (home / "chromium.log").string();
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
  const int rc = posix_spawn(&pid_, chromium.c_str(), &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  close(in[0]);
  close(out[1]);
  to_browser_ = in[1];
  from_browser_ = out[0];
  if (rc != 0) {
    ADD_FAILURE() << "cannot start chromium: " << std::strerror(rc);
    pid_ = -1;
    return;
  }
  // A page of its own, attached in flat mode: its commands then carry the session id.
  const Json target = command("Target.createTarget", {{"url", "about:blank"}}, false);
  if (!target.contains("targetId")) return;
  const Json attached = command("Target.attachToTarget",
                                {{"targetId", target["targetId"]}, {"flatten", true}}, false);
  if (!attached.contains("sessionId")) return;
  session_ = attached["sessionId"].get<std::string>();
  command("Page.enable", Json::object(), true);
  command("Runtime.enable", Json::object(), true);
  command("Emulation.setDeviceMetricsOverride",
          {{"width", width}, {"height", height}, {"deviceScaleFactor", 1}, {"mobile", false}},
          true);
}

ChromiumPage::~ChromiumPage() {
  if (to_browser_ >= 0) close(to_browser_);  // Chromium quits when its pipe closes
  if (pid_ > 0) {
    const auto start = std::chrono::steady_clock::now();
    int status = 0;
    while (waitpid(pid_, &status, WNOHANG) == 0) {
      if (secondsFrom(start) > 5) {
        kill(pid_, SIGKILL);
        waitpid(pid_, &status, 0);
        break;
      }
      usleep(20000);
    }
  }
  if (from_browser_ >= 0) close(from_browser_);
}

void ChromiumPage::handleEvent(const Json& m) {
  const std::string method = m.value("method", "");
  if (method == "Page.loadEventFired") loaded_ = true;
  if (method == "Runtime.consoleAPICalled") {
    for (const Json& a : m["params"]["args"]) {
      console_ += a.contains("value") ? a["value"].dump() : a.value("description", "?");
      console_ += ' ';
    }
    console_ += '\n';
  }
  if (method == "Runtime.exceptionThrown") {
    console_ += "exception: " + m["params"]["exceptionDetails"].dump() + "\n";
  }
}

bool ChromiumPage::readUntil(const std::function<bool(const Json&)>& done, double timeout_s) {
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    for (std::size_t end; (end = buffer_.find('\0')) != std::string::npos;) {
      const Json m = Json::parse(buffer_.substr(0, end), nullptr, false);
      buffer_.erase(0, end + 1);
      if (m.is_discarded()) continue;
      handleEvent(m);
      if (done(m)) return true;
    }
    const double left = timeout_s - secondsFrom(start);
    if (left <= 0) return false;
    pollfd p{from_browser_, POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(left * 1000) + 1) <= 0) continue;
    char chunk[65536];
    const ssize_t n = read(from_browser_, chunk, sizeof chunk);
    if (n <= 0) return false;  // the browser is gone
    buffer_.append(chunk, static_cast<std::size_t>(n));
  }
}

Json ChromiumPage::command(const std::string& method, const Json& params, bool in_page,
                           double timeout_s) {
  if (to_browser_ < 0 || pid_ <= 0) return nullptr;
  const int id = next_id_++;
  Json message = {{"id", id}, {"method", method}, {"params", params}};
  if (in_page) message["sessionId"] = session_;
  std::string text = message.dump();
  text.push_back('\0');
  for (std::size_t sent = 0; sent < text.size();) {
    const ssize_t n = write(to_browser_, text.data() + sent, text.size() - sent);
    if (n <= 0) {
      ADD_FAILURE() << "chromium: cannot send " << method;
      return nullptr;
    }
    sent += static_cast<std::size_t>(n);
  }
  Json reply;
  if (!readUntil([&](const Json& m) {
        if (m.value("id", -1) != id) return false;
        reply = m;
        return true;
      }, timeout_s)) {
    ADD_FAILURE() << "chromium did not answer " << method << " within " << timeout_s << " s";
    return nullptr;
  }
  if (reply.contains("error")) {
    ADD_FAILURE() << "chromium: " << method << ": " << reply["error"].dump();
    return nullptr;
  }
  return reply.value("result", Json::object());
}

void ChromiumPage::navigate(const std::string& url, double timeout_s) {
  loaded_ = false;
  command("Page.navigate", {{"url", url}}, true, timeout_s);
  if (!loaded_ && !readUntil([&](const Json&) { return loaded_; }, timeout_s)) {
    ADD_FAILURE() << url << " did not load within " << timeout_s << " s";
  }
}

Json ChromiumPage::evaluate(const std::string& expression, double timeout_s) {
  const Json r = command("Runtime.evaluate",
                         {{"expression", expression}, {"returnByValue", true},
                          {"awaitPromise", true}},
                         true, timeout_s);
  if (r.is_null()) return nullptr;
  if (r.contains("exceptionDetails")) {
    ADD_FAILURE() << "in the page: " << expression << "\n" << r["exceptionDetails"].dump();
    return nullptr;
  }
  return r["result"].value("value", Json());
}

bool ChromiumPage::waitFor(const std::string& expression, double timeout_s) {
  const auto start = std::chrono::steady_clock::now();
  while (secondsFrom(start) < timeout_s) {
    const Json v = evaluate("!!(" + expression + ")");
    if (v.is_boolean() && v.get<bool>()) return true;
    if (v.is_null()) return false;
    readUntil([](const Json&) { return false; }, 0.1);  // events meanwhile; a short pause
  }
  return false;
}

void ChromiumPage::click(double x, double y) {
  command("Input.dispatchMouseEvent", {{"type", "mouseMoved"}, {"x", x}, {"y", y}}, true);
  for (const char* type : {"mousePressed", "mouseReleased"}) {
    command("Input.dispatchMouseEvent",
            {{"type", type}, {"x", x}, {"y", y}, {"button", "left"}, {"clickCount", 1},
             {"buttons", std::string(type) == "mousePressed" ? 1 : 0}},
            true);
  }
}

void ChromiumPage::key(const std::string& key) {
  Json down = {{"type", "keyDown"}, {"key", key}};
  if (key.size() == 1) {
    down["text"] = key;
    down["code"] = key == " " ? std::string("Space")
                              : std::string("Key").append(
                                    1, static_cast<char>(std::toupper(static_cast<unsigned char>(key[0]))));
  } else {
    down["code"] = key;
  }
  command("Input.dispatchKeyEvent", down, true);
  command("Input.dispatchKeyEvent", {{"type", "keyUp"}, {"key", key}, {"code", down["code"]}},
          true);
}

}  // namespace objscan::testing
