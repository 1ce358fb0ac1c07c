// objscan scan/fuse --serve: the live page server against the real objscan binary, scanning a
// synthetic recording and the virtual OpenNI2 sensor at 30 Hz. live_server_test (label unit, also under the sanitizers):
// hostile requests and a busy port. live_page_test (label live): the page in headless Chromium.

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "background_process.h"
#include "browser.h"
#include "http_client.h"
#include "cli_expect.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using testing::BackgroundProcess;
using testing::TempDir;

using testing::Answer;
using testing::askRaw;
using testing::connectTo;
using testing::get;
using testing::portOf;

/// The N of the summary's "frames        N read, ..." line; 0 when there is none.
[[maybe_unused]] std::size_t framesRead(const std::string& out) {
  const std::size_t at = out.find("\nframes        ");
  return at == std::string::npos ? 0 : std::stoul(out.substr(at + 15));
}

/// The state a served run's page ends with: waits for the run to print its address and then
/// that it shows the results, and asks for the state; null (the test failed) when either line
/// did not come or the state could not be had. `port` receives the port.
[[maybe_unused]] nlohmann::json finalState(BackgroundProcess& run, int* port) {
  *port = portOf(run.waitForLine("live page", 60));
  if (*port <= 0) {
    ADD_FAILURE() << "no address printed\n" << run.out() << run.err();
    return nullptr;
  }
  if (run.waitForLine("live page     http://127.0.0.1:" + std::to_string(*port) + "/ shows", 300)
          .empty()) {
    ADD_FAILURE() << "the run did not end\n" << run.out() << run.err();
    return nullptr;
  }
  const Answer state = get(*port, "/api/state?after=0");
  EXPECT_EQ(state.status, 200);
  return state.status == 200 ? nlohmann::json::parse(state.body) : nlohmann::json();
}

/// A scan of `frames` frames of `source` into `out`, serving on a free port, and kept serving
/// afterwards until Ctrl-C.
std::vector<std::string> servedScan(const std::string& source, const fs::path& out, int frames) {
  return {OBJSCAN_EXE, "scan",      source,        "--frames",     std::to_string(frames),
          "--out",     out.string(), "--serve",    "127.0.0.1:0",  "--no-catalog",
          "--live-discovery-every", "1"};
}

#ifndef OBJSCAN_LIVE_PAGE_TEST
TEST(LiveServer, HostileRequestsGet4xxAndTheScanGoesOn) {
  TempDir dir;
  const fs::path out = dir / "out";
  fs::create_directories(out);
  // Files the server must never hand out: a link to outside the folder, and a hidden file.
  fs::create_symlink("/etc/passwd", out / "outside");
  testing::writeBytes(out / ".hidden", "secret\n");
  // A synthetic recording, read as fast as fusion goes and never skipping a frame, so that an
  // unharmed scan fuses each of its 60 frames however slow the build (a sanitizer's) is.
  BackgroundProcess scan(servedScan("synth:7", out, 60));
  const int port = portOf(scan.waitForLine("live page", 60));
  ASSERT_GT(port, 0) << scan.out() << scan.err();

  // While it fuses.
  EXPECT_EQ(get(port, "/").status, 200);
  EXPECT_EQ(get(port, "/nope").status, 404);
  EXPECT_EQ(get(port, "/results/report.html").status, 404);  // not written yet
  for (const std::string target :
       {"/results/../../../../etc/passwd", "/results/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
        "/results/..%2f..%2f..%2fetc%2fpasswd", "/../../etc/passwd", "/results/outside",
        "/results/.hidden", "/results//etc/passwd", "/results/", "/results/%00",
        "/results/..%5c..%5cetc%5cpasswd"}) {
    const Answer a = get(port, target);
    EXPECT_GE(a.status, 400) << target;
    EXPECT_LT(a.status, 500) << target;
    EXPECT_EQ(a.body.find("root:"), std::string::npos) << target;
    EXPECT_EQ(a.body.find("secret"), std::string::npos) << target;
  }
  const std::string own = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";
  EXPECT_EQ(askRaw(port, "POST /api/state HTTP/1.1\r\n" + own +
                             "Content-Length: 5\r\nConnection: close\r\n\r\nhello")
                .status,
            405);
  EXPECT_EQ(askRaw(port, "PUT /results/new.txt HTTP/1.1\r\n" + own +
                             "Content-Length: 5\r\nConnection: close\r\n\r\nhello")
                .status,
            405);
  // Another site's name made to point at 127.0.0.1 (DNS rebinding), or another port: refused.
  EXPECT_EQ(get(port, "/api/state", "attacker.example:" + std::to_string(port)).status, 403);
  EXPECT_EQ(get(port, "/", "127.0.0.1:" + std::to_string(port + 1)).status, 403);
  EXPECT_EQ(get(port, "/", "127.0.0.1").status, 403);
  EXPECT_EQ(get(port, "/", "LOCALHOST:" + std::to_string(port)).status, 200);
  // A header of 64 kB: over civetweb's 16 kB request limit.
  const Answer huge = askRaw(port, "GET / HTTP/1.1\r\nHost: x\r\nX-Big: " +
                                         std::string(64 * 1024, 'a') + "\r\n\r\n");
  EXPECT_TRUE(huge.status == 0 || (huge.status >= 400 && huge.status < 500)) << huge.status;
  const Answer garbage = askRaw(port, std::string("\x16\x03\x01\x02\x00 \xff\xfe\r\n\r\n", 12));
  EXPECT_TRUE(garbage.status == 0 || (garbage.status >= 400 && garbage.status < 500))
      << garbage.status;
  // Many connections at once, half of them sending an unfinished request, then gone.
  std::vector<int> crowd;
  for (int i = 0; i < 100; ++i) {
    const int fd = connectTo(port);
    if (fd < 0) continue;
    if (i % 2 == 0) ::send(fd, "GET / HTTP/1.1\r\nHost:", 21, MSG_NOSIGNAL);
    crowd.push_back(fd);
  }
  EXPECT_GE(crowd.size(), 50u);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  for (const int fd : crowd) ::close(fd);
  EXPECT_EQ(get(port, "/api/state").status, 200);

  // The scan was not harmed: every frame fused, every output written; the page still answers.
  const std::string shows = scan.waitForLine("live page     http://127.0.0.1:" +
                                                 std::to_string(port) + "/ shows",
                                             300);
  ASSERT_NE(shows, "") << scan.out() << scan.err();
  EXPECT_NE(scan.out().find("frames        60 read, 60 fused, 0 lost"), std::string::npos)
      << scan.out();
  const Answer state = get(port, "/api/state");
  ASSERT_EQ(state.status, 200);
  const nlohmann::json j = nlohmann::json::parse(state.body);
  EXPECT_EQ(j["stage"], "done");
  EXPECT_EQ(j["frames"]["fused"], 60);
  EXPECT_EQ(get(port, "/results/report.html").status, 200);
  EXPECT_EQ(get(port, "/results/objects/rank_001.ply").status, 200);
  // The same file by an encoded slash or backslash, or with an encoded NUL (which ended the
  // path) or control character: refused, though the file is there.
  for (const std::string target :
       {"/results/objects%2frank_001.ply", "/results/objects%2Frank_001.ply",
        "/results/objects%5crank_001.ply", "/results/report.html%00.txt",
        "/results/report.html%0d%0a", "/results/report.html%"}) {
    const Answer a = get(port, target);
    EXPECT_GE(a.status, 400) << target;
    EXPECT_LT(a.status, 500) << target;
  }
  // Clients that go away in the middle of a download (a reset, not a close): the server goes on.
  for (int i = 0; i < 10; ++i) {
    const int fd = connectTo(port);
    ASSERT_GE(fd, 0);
    const std::string request =
        "GET /results/mesh.ply HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) + "\r\n\r\n";
    ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
    char some[100];
    ::recv(fd, some, sizeof some, 0);
    const linger reset{1, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
    ::close(fd);
  }
  EXPECT_EQ(get(port, "/api/state").status, 200);
  EXPECT_FALSE(fs::exists(out / "new.txt"));
  scan.signal(SIGINT);  // ends the serving after the scan
  EXPECT_EQ(scan.wait(60), 0) << scan.err();
  EXPECT_TRUE(fs::is_regular_file(out / "report.html"));
  EXPECT_EQ(connectTo(port), -1);  // the server is gone with the process
}

/// A listening socket on a free port of 127.0.0.1, held by the test.
class BusyPort {
 public:
  BusyPort() {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof address;
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        ::listen(fd_, 1) != 0 ||
        ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &size) != 0) {
      throw std::runtime_error("cannot hold a port");
    }
    port_ = ntohs(address.sin_port);
  }
  ~BusyPort() { ::close(fd_); }
  int port() const { return port_; }

 private:
  int fd_ = -1;
  int port_ = 0;
};

TEST(LiveServer, APortInUseIsOneErrorBeforeAnythingIsWritten) {
  TempDir dir;
  const BusyPort busy;
  const std::string address = "127.0.0.1:" + std::to_string(busy.port());
  testing::expectOneErrorLine(
      testing::objscan({"scan", "synth:3", "--frames", "5", "--out", (dir / "s").string(),
                        "--serve", address, "--no-catalog"}),
      2, "--serve " + address + ": cannot listen");
  EXPECT_FALSE(fs::exists(dir / "s"));
  testing::expectOneErrorLine(testing::objscan({"fuse", "synth:3", "--end", "5", "--out",
                                                (dir / "f").string(), "--serve", address}),
                              2, "cannot listen");
  EXPECT_FALSE(fs::exists(dir / "f"));
  // An address that is not this machine's (TEST-NET-1, RFC 5737) cannot be listened on either.
  testing::expectOneErrorLine(
      testing::objscan({"scan", "synth:3", "--frames", "5", "--out", (dir / "n").string(),
                        "--serve", "192.0.2.1:8080", "--no-catalog"}),
      2, "--serve 192.0.2.1:8080: cannot listen");
  EXPECT_FALSE(fs::exists(dir / "n"));
}

TEST(LiveServer, BadServeValuesAreUsageErrors) {
  TempDir dir;
  for (const auto& [value, needle] : std::vector<std::pair<std::string, std::string>>{
           {"70000", "the port must be a number from 0 to 65535"},
           {"http", "the port must be a number"},
           {"-1", "the port must be a number"},
           {"example.com:8080", "is not an IPv4 address"},
           {"1.2.3:8080", "is not an IPv4 address"},
           {":8080", "is not an IPv4 address"}}) {
    testing::expectOneErrorLine(
        testing::objscan({"scan", "synth:3", "--out", (dir / "s").string(), "--serve", value}), 2,
        needle);
  }
  EXPECT_FALSE(fs::exists(dir / "s"));
}

// Ctrl-C while a served scan fuses a recording ends the scan and the server together, with the
// outputs a stopped scan writes without --serve, and no waiting for the page.
TEST(LiveServer, CtrlCEndsTheScanAndTheServerTogether) {
  TempDir dir;
  const fs::path out = dir / "out";
  BackgroundProcess scan(servedScan("synth:7", out, 300));
  const int port = portOf(scan.waitForLine("live page", 60));
  ASSERT_GT(port, 0) << scan.out() << scan.err();
  // Wait until a frame is fused (the page has a picture), however slow the build.
  bool fused = false;
  for (int i = 0; i < 600 && !fused; ++i) {
    fused = get(port, "/api/model.jpg").status == 200;
    if (!fused) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(fused) << scan.err();
  scan.signal(SIGINT);
  // A page that is watching is told before the server goes.
  std::string outcome;
  std::uint64_t seq = 0;
  for (int i = 0; i < 300 && outcome.empty(); ++i) {
    const Answer state = get(port, "/api/state?after=" + std::to_string(seq));  // long polls
    if (state.status != 200) break;
    const nlohmann::json j = nlohmann::json::parse(state.body);
    seq = j["seq"];
    if (!j["final"].is_null()) outcome = j["final"]["outcome"];
  }
  EXPECT_EQ(outcome.rfind("stopped by Ctrl-C / SIGTERM; not produced: hypotheses.json", 0), 0u)
      << outcome;
  EXPECT_EQ(scan.wait(120), 130) << scan.err();
  EXPECT_NE(scan.out().find("stopped by    Ctrl-C / SIGTERM; not produced: hypotheses.json"),
            std::string::npos)
      << scan.out();
  EXPECT_EQ(scan.out().find("shows the results"), std::string::npos) << scan.out();
  EXPECT_TRUE(fs::is_regular_file(out / "mesh.ply"));
  EXPECT_TRUE(fs::is_regular_file(out / "timings.json"));
  EXPECT_EQ(connectTo(port), -1);
}

// A source whose name is not UTF-8 (a folder named in Latin-1): the state is still served, and
// the results files written, with U+FFFD in its place (before, the run failed at its end with
// nlohmann's "invalid UTF-8 byte" while writing settings.json).
TEST(LiveServer, ASourceNamedInLatin1IsServed) {
  TempDir dir;
  const fs::path folder = dir / "desk\xe9";  // "deské" in Latin-1
  ASSERT_EQ(testing::objscan({"synth", "--out", folder.string(), "--frames", "8", "--objects",
                              "2"})
                .exit_code,
            0);
  BackgroundProcess fuse({OBJSCAN_EXE, "fuse", folder.string(), "--out", (dir / "f").string(),
                          "--serve", "0", "--serve-wait", "30", "--no-live-discovery"});
  int port = 0;
  const nlohmann::json j = finalState(fuse, &port);
  ASSERT_FALSE(j.is_null());
  EXPECT_NE(j["source"].get<std::string>().find("desk\xef\xbf\xbd"), std::string::npos);
  EXPECT_EQ(j["final"]["outcome"], "finished");
  // settings.json names the source too, the same way.
  EXPECT_NE(testing::readBytes(dir / "f" / "settings.json").find("desk\xef\xbf\xbd"),
            std::string::npos);
  fuse.signal(SIGTERM);
  EXPECT_EQ(fuse.wait(60), 0) << fuse.err();
  EXPECT_TRUE(fs::is_regular_file(dir / "f" / "mesh.ply"));
}

// Fusion ending while an online discovery round runs on the volume's copy (rounds back to back,
// every 0.1 s): the round's copy stays alive until the round ends (it was freed under it once,
// when the stage changed twice), and the run ends cleanly.
TEST(LiveServer, FusionEndingDuringADiscoveryRoundIsClean) {
  TempDir dir;
  for (int run = 0; run < 3; ++run) {
    const fs::path out = dir / std::string("f").append(std::to_string(run));
    const testing::ProcessResult r =
        testing::objscan({"fuse", "synth:3", "--end", "40", "--out", out.string(), "--serve", "0",
                          "--serve-wait", "0", "--live-discovery-every", "0.1"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::is_regular_file(out / "mesh.ply"));
  }
}

/// fuse --serve: the page's state follows the fusion and ends with the mesh linked.
TEST(LiveServer, FuseServesTheFinalState) {
  TempDir dir;
  BackgroundProcess fuse({OBJSCAN_EXE, "fuse", "synth:3", "--end", "20", "--out",
                          (dir / "f").string(), "--serve", "0", "--no-live-discovery"});
  int port = 0;
  const nlohmann::json j = finalState(fuse, &port);
  ASSERT_FALSE(j.is_null());
  EXPECT_EQ(j["command"], "fuse");
  EXPECT_EQ(j["frames"]["fused"], 20);
  EXPECT_EQ(j["final"]["outcome"], "finished");
  EXPECT_TRUE(j["discovery"].is_null());
  EXPECT_EQ(j["final"]["files"][0]["href"], "/results/mesh.ply");
  const Answer mesh = get(port, "/results/mesh.ply");
  EXPECT_EQ(mesh.status, 200);
  EXPECT_EQ(mesh.body, testing::readBytes(dir / "f" / "mesh.ply"));
  // An encoded NUL ended the path, so these were the mesh and the state: refused now.
  for (const std::string target : {"/results/mesh.ply%00.txt", "/api/state%00x",
                                   "/api/model.jpg%00", "/results/mesh%2eply%00"}) {
    const Answer a = get(port, target);
    EXPECT_GE(a.status, 400) << target;
    EXPECT_LT(a.status, 500) << target;
  }
  EXPECT_EQ(get(port, "/api/model.jpg").body.substr(0, 3), "\xff\xd8\xff");  // a JPEG
  fuse.signal(SIGTERM);
  EXPECT_EQ(fuse.wait(60), 0) << fuse.err();
}

#else
/// The value of attribute `name` of the <body> element of a serialised DOM.
std::string bodyAttribute(const std::string& dom, const std::string& name) {
  const std::size_t body = dom.find("<body");
  if (body == std::string::npos) return "(no body)";
  const std::string tag = dom.substr(body, dom.find('>', body) - body);
  const std::size_t at = tag.find(" " + name + "=\"");
  if (at == std::string::npos) return "(absent)";
  const std::size_t begin = at + name.size() + 3;
  return tag.substr(begin, tag.find('"', begin) - begin);
}

// The page in headless Chromium while a 30 Hz virtual sensor is scanned: the model picture
// changes while frames arrive, hypotheses appear before the scan ends, and the final state (with
// the report linked) is shown. The page writes what it saw into <body>'s data attributes.
TEST(LivePage, FollowsAScanInChromium) {
  TempDir dir;
  const fs::path out = dir / "out";
  constexpr int kFrames = 240;  // 8 s at 30 Hz: time for Chromium to start on a loaded machine
  BackgroundProcess scan(servedScan("virtual:synth:7?fps=30", out, kFrames));
  const std::string line = scan.waitForLine("live page", 60);
  ASSERT_GT(portOf(line), 0) << scan.out() << scan.err();
  const std::string url = line.substr(line.find("http"));
  // 120 s of the page's virtual time: it stands still while a request is open, and the page
  // stops asking once it has shown the final state, so Chromium returns soon after the scan ends.
  const std::string dom = testing::domInChromium(url, 120000, 170);
  EXPECT_GE(std::stoi(bodyAttribute(dom, "data-distinct-pictures")), 5) << dom;
  EXPECT_EQ(bodyAttribute(dom, "data-hypotheses-before-end"), "yes");
  const int first_hypotheses = std::stoi(bodyAttribute(dom, "data-hypotheses-frame"));
  EXPECT_GE(first_hypotheses, 0);
  EXPECT_LT(first_hypotheses, kFrames - 1);
  EXPECT_EQ(bodyAttribute(dom, "data-final").rfind("finished: ", 0), 0u)
      << bodyAttribute(dom, "data-final");
  EXPECT_EQ(bodyAttribute(dom, "data-report"), "/results/report.html");
  EXPECT_EQ(bodyAttribute(dom, "data-errors"), "0");
  EXPECT_NE(dom.find("<a href=\"/results/report.html\">report</a>"), std::string::npos);
  scan.signal(SIGINT);
  EXPECT_EQ(scan.wait(60), 0) << scan.err();
  EXPECT_GE(framesRead(scan.out()), 20u) << scan.out();
}
#endif

}  // namespace
}  // namespace objscan
