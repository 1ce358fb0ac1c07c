// objscan view: the viewer's server against the real objscan binary on a real scan of a
// synthetic scene (view_server_test, label unit, also under the sanitizers): its routes, hostile
// and malformed requests, bad folders, and labels from two viewers and many threads at once
// reaching the catalog intact. view_page_test (label live): the page in headless Chromium, driven
// by real clicks and keys: the canvas draws the scene, a click selects, labels made with the
// keyboard arrive in the catalog, and train on them gives a model discover accepts.

#include <gtest/gtest.h>
#include <poll.h>
#include <sqlite3.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "background_process.h"
#include "browser.h"
#include "cli_expect.h"
#include "http_client.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/ply_io.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/scenes.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing::Answer;
using testing::BackgroundProcess;
using testing::get;
using testing::portOf;
using testing::post;
using testing::ProcessResult;
using testing::TempDir;

ProcessResult objscan(std::vector<std::string> args) {
  args.insert(args.begin(), OBJSCAN_EXE);
  return testing::runProcess(args);
}

/// A scan of a synthetic desk (6 objects, 40 frames) into DIR/res, its catalog DIR/cat.sqlite,
/// and the scene's ground truth DIR/syn/scene_gt.ply. Made once for the whole test program.
const fs::path& scannedScene() {
  static TempDir dir;
  static const bool made = [] {
    ProcessResult r = objscan({"synth", "--out", (dir / "syn").string(), "--frames", "40",
                               "--objects", "6", "--seed", "3"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    r = objscan({"scan", (dir / "syn").string(), "--out", (dir / "res").string(), "--catalog",
                 (dir / "cat.sqlite").string()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.exit_code == 0;
  }();
  EXPECT_TRUE(made);
  return dir.path();
}

/// A copy of the scanned results and catalog in a fresh folder, so that a test's labels are its
/// own. The copy's hypotheses.json names the copy's catalog.
fs::path freshCopy(const TempDir& into) {
  const fs::path& source = scannedScene();
  fs::copy(source / "res", into / "res", fs::copy_options::recursive);
  fs::copy_file(source / "cat.sqlite", into / "cat.sqlite");
  json doc = json::parse(readWholeFile(into / "res" / "hypotheses.json"));
  doc["catalog"]["path"] = (into / "cat.sqlite").string();
  std::ofstream(into / "res" / "hypotheses.json") << doc.dump();
  return into / "res";
}

/// `objscan view DIR --serve 127.0.0.1:0` in the background, serving for at most 120 s.
std::unique_ptr<BackgroundProcess> startView(const fs::path& dir, int* port,
                                             std::vector<std::string> extra = {}) {
  std::vector<std::string> args = {OBJSCAN_EXE,   "view",         dir.string(), "--serve",
                                   "127.0.0.1:0", "--serve-wait", "120",        "--labeller",
                                   "tester"};
  args.insert(args.end(), extra.begin(), extra.end());
  auto view = std::make_unique<BackgroundProcess>(args);
  *port = portOf(view->waitForLine("viewer", 60));
  EXPECT_GT(*port, 0) << view->out() << view->err();
  // It listens first and reads the scenes after; this line says it has.
  EXPECT_FALSE(view->waitForLine("scenes", 60).empty()) << view->out() << view->err();
  return view;
}

[[maybe_unused]] json jsonOf(const Answer& a) { return json::parse(a.body, nullptr, false); }

/// The catalog's labels of every segment of the first scene: id -> label (absent: none).
std::map<std::int64_t, int> catalogLabels(const fs::path& catalog, std::string* by = nullptr) {
  discovery::Catalog c(catalog);
  std::map<std::int64_t, int> out;
  for (const discovery::CatalogSegment& s : c.segments(c.scenes().at(0).id, false)) {
    if (s.label) out[s.id] = *s.label;
    if (s.label && by) *by = s.labelled_by;
  }
  return out;
}

[[maybe_unused]] std::string integrityOf(const fs::path& catalog) {
  sqlite3* db = nullptr;
  std::string result;
  if (sqlite3_open_v2(catalog.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_exec(
        db, "PRAGMA integrity_check",
        [](void* out, int, char** values, char**) {
          *static_cast<std::string*>(out) += values[0] ? values[0] : "";
          return 0;
        },
        &result, nullptr);
  }
  sqlite3_close(db);
  return result;
}

#ifndef OBJSCAN_VIEW_PAGE_TEST

TEST(ViewServer, ServesTheResultsTheMeshAndTheCandidates) {
  TempDir dir;
  const fs::path res = freshCopy(dir);
  int port = 0;
  auto view = startView(res, &port);
  ASSERT_GT(port, 0);
  const json results = jsonOf(get(port, "/api/results"));
  ASSERT_TRUE(results.is_object());
  ASSERT_EQ(results["scenes"].size(), 1u);
  const json& scene = results["scenes"][0];
  EXPECT_TRUE(scene["labelling"].get<bool>()) << results.dump();
  EXPECT_FALSE(scene.contains("error"));
  const json hypotheses = json::parse(readWholeFile(res / "hypotheses.json"))["hypotheses"];
  ASSERT_EQ(results["hypotheses"].size(), hypotheses.size());
  EXPECT_EQ(results["hypotheses"][0]["file"], "objects/rank_001.ply");
  EXPECT_EQ(results["labeller"], "tester");
  // The object set's members carry the object score they are ranked by; alternatives none.
  for (std::size_t k = 0; k < hypotheses.size(); ++k) {
    const json& served = results["hypotheses"][k];
    if (hypotheses[k]["object_set"].get<bool>()) {
      EXPECT_EQ(served["object_score"], hypotheses[k]["object_score"]) << k;
    } else {
      EXPECT_TRUE(served["object_score"].is_null()) << k;
    }
    EXPECT_EQ(served["footing"], hypotheses[k]["context"]["footing"]) << k;
  }

  // The mesh: the OSVM form with the scan's own vertex and triangle counts (not decimated).
  const Answer mesh = get(port, "/api/scenes/0/mesh");
  ASSERT_EQ(mesh.status, 200);
  ASSERT_GE(mesh.body.size(), 20u);
  EXPECT_EQ(mesh.body.substr(0, 4), "OSVM");
  const TriangleMesh scan = readPly(res / "mesh.ply");
  const auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, mesh.body.data() + at, 4);
    return v;
  };
  EXPECT_EQ(u32(8), scan.positions.size());
  EXPECT_EQ(u32(12), scan.triangles.size());

  // Hypothesis 1's vertices on the preview are its vertex list (no decimation: the same).
  const Answer first = get(port, "/api/scenes/0/hypotheses/1/vertices");
  ASSERT_EQ(first.status, 200);
  EXPECT_EQ(first.body.size(), 4 * hypotheses[0]["vertices"].size());

  // Every candidate of the catalog, the ranked ones first and marked with their rank.
  const json segments = jsonOf(get(port, "/api/scenes/0/segments"));
  discovery::Catalog catalog(dir / "cat.sqlite");
  const auto rows = catalog.segments(catalog.scenes().at(0).id, false);
  ASSERT_EQ(segments["segments"].size(), rows.size());
  EXPECT_EQ(segments["progress"]["segments"], rows.size());
  EXPECT_EQ(segments["segments"][0]["rank"], 1);
  std::size_t ranked = 0;
  for (const json& s : segments["segments"]) ranked += s["rank"].is_null() ? 0 : 1;
  EXPECT_GT(rows.size(), ranked) << "candidates below the ranking are offered too";

  // The segment on a vertex of hypothesis 1 includes hypothesis 1's segment.
  std::uint32_t vertex = 0;
  std::memcpy(&vertex, first.body.data(), 4);
  const json at = jsonOf(get(port, "/api/scenes/0/at?vertex=" + std::to_string(vertex)));
  const std::vector<std::int64_t> ids = at["segments"].get<std::vector<std::int64_t>>();
  EXPECT_NE(std::find(ids.begin(), ids.end(), segments["segments"][0]["id"].get<std::int64_t>()),
            ids.end());

  // A hypothesis's PLY downloads from the results folder, byte for byte; a page of the folder
  // runs sandboxed (it cannot use the API as the user); the page and scripts are served.
  const Answer ply = get(port, "/results/objects/rank_001.ply");
  EXPECT_EQ(ply.status, 200);
  EXPECT_EQ(ply.body, readWholeFile(res / "objects" / "rank_001.ply"));
  const Answer report = get(port, "/results/report.html");
  EXPECT_EQ(report.status, 200);
  EXPECT_NE(report.headers.find("Content-Security-Policy: sandbox allow-scripts"), std::string::npos)
      << report.headers;
  EXPECT_NE(report.headers.find("Content-Type: text/html"), std::string::npos) << report.headers;
  EXPECT_EQ(get(port, "/").status, 200);
  const Answer three = get(port, "/assets/three.min.js");
  EXPECT_EQ(three.status, 200);
  EXPECT_NE(three.body.find("REVISION=\"111\""), std::string::npos);
  EXPECT_EQ(get(port, "/assets/mesh_view.js").status, 200);
  view->signal(SIGINT);
  EXPECT_EQ(view->wait(10), 0) << view->err();
}

TEST(ViewServer, HostileAndMalformedRequestsGet4xxAndTheCatalogStaysWhole) {
  TempDir dir;
  const fs::path res = freshCopy(dir);
  fs::create_symlink("/etc/passwd", res / "passwd");
  int port = 0;
  auto view = startView(res, &port);
  ASSERT_GT(port, 0);
  const json segments = jsonOf(get(port, "/api/scenes/0/segments"));
  const std::int64_t id = segments["segments"][0]["id"];
  const std::string label = R"({"segment": )" + std::to_string(id) + R"(, "label": "object"})";

  // Only its own routes and files inside the folder.
  for (const char* target :
       {"/results/../cat.sqlite", "/results/%2e%2e/cat.sqlite", "/results/passwd",
        "/results/..%2fcat.sqlite", "/results/.lock", "/results/", "/results/objects",
        "/api/scenes/1/mesh", "/api/scenes/-1/mesh", "/api/scenes/0x0/mesh",
        "/api/scenes/99999999999999999999/mesh", "/api/scenes/0/segments/1/../../mesh",
        "/api/scenes/0/hypotheses/0/vertices", "/api/scenes/0/segments/abc/vertices", "/etc/passwd",
        "/assets/../../etc/passwd",
        // An encoded NUL (it ended the path: this named mesh.ply) or slash, a control character,
        // a malformed escape.
        "/results/mesh.ply%00.txt", "/results/objects%2frank_001.ply",
        "/results/objects%2Frank_001.ply", "/results/objects%5crank_001.ply", "/api/results%00x",
        "/api/scenes/0/mesh%00", "/results/mesh.ply%0a", "/results/mesh.ply%",
        "/results/%zzmesh.ply"}) {
    const Answer a = get(port, target);
    EXPECT_TRUE(a.status >= 400 && a.status < 500) << target << ": " << a.status;
    EXPECT_EQ(a.body.find("root:"), std::string::npos) << target;
  }
  // What the rules refuse is refused for what it is, not as a missing file: the same names
  // sent plainly are served.
  EXPECT_EQ(get(port, "/results/objects/rank_001.ply").status, 200);
  EXPECT_EQ(get(port, "/results/%6Desh.ply").status, 200);  // %6D is m
  EXPECT_EQ(get(port, "/api/scenes/0/at?vertex=x").status, 400);
  EXPECT_EQ(get(port, "/api/scenes/0/at?vertex=4294969232").status, 400) << "no 32-bit wrap";
  EXPECT_EQ(get(port, "/api/results", "evil.example:" + std::to_string(port)).status, 403);

  // Labels: JSON only, from this server's own pages, small, well-formed.
  EXPECT_EQ(post(port, "/api/label", label, "text/plain").status, 415);
  EXPECT_EQ(post(port, "/api/label", label, "").status, 415);
  // The media type exactly: not one that only starts the same.
  for (const char* type : {"application/jsonx", "application/json-patch+json", "application/js",
                           "application/json5; charset=utf-8"}) {
    EXPECT_EQ(post(port, "/api/label", label, type).status, 415) << type;
  }
  EXPECT_EQ(post(port, "/api/label", label, "application/json", "Origin: http://evil.example\r\n")
                .status,
            403);
  EXPECT_EQ(post(port, "/api/label", std::string(5000, '{')).status, 413);
  EXPECT_EQ(post(port, "/api/label", "{\"segment\": ").status, 400);
  EXPECT_EQ(post(port, "/api/label", "[1, 2]").status, 400);
  EXPECT_EQ(post(port, "/api/label", R"({"segment": "1", "label": "object"})").status, 400);
  EXPECT_EQ(post(port, "/api/label", R"({"segment": 1e3, "label": "object"})").status, 400);
  EXPECT_EQ(post(port, "/api/label",
                 R"({"segment": )" + std::to_string(id) + R"(, "label": "maybe"})")
                .status,
            400);
  EXPECT_EQ(post(port, "/api/label",
                 R"({"segment": )" + std::to_string(id) + R"(, "label": "object", "by": "a\u0007b"})")
                .status,
            400);
  // Names a terminal would obey or that show nothing: escapes, text-direction characters,
  // invisible spaces only, a leading byte order mark, an empty one (it does not fall back).
  for (const char* by :
       {R"("   ")", R"("a\u202eb")", R"("a\u0085b")", R"("a\u2028b")", R"("a\u001b[2Jb")",
        R"("\u200f")", R"("\u200b\u00a0\u3000")", R"("\ufeffana")", R"("")", R"(42)"}) {
    EXPECT_EQ(post(port, "/api/label",
                   R"({"segment": )" + std::to_string(id) + R"(, "label": "object", "by": )" + by +
                       "}")
                  .status,
              400)
        << by;
  }
  // 64 characters are a name, even when they take 128 bytes.
  std::string accents;
  for (int i = 0; i < 64; ++i) accents += "\u00e9";
  const Answer long_name = post(port, "/api/label", R"({"segment": )" + std::to_string(id) +
                                                        R"(, "label": "object", "by": ")" + accents + "\"}");
  EXPECT_EQ(long_name.status, 200) << long_name.body;
  EXPECT_EQ(post(port, "/api/label", R"({"segment": )" + std::to_string(id) + R"(, "label": null})").status,
            200);
  EXPECT_EQ(post(port, "/api/label", R"({"segment": 987654321, "label": "object"})").status, 404);
  EXPECT_EQ(post(port, "/api/undo", R"({"event": 987654321})").status, 404);
  EXPECT_EQ(post(port, "/api/state", "{}").status, 405);
  EXPECT_EQ(testing::askRaw(port, "PUT /api/label HTTP/1.1\r\nHost: 127.0.0.1:" +
                                      std::to_string(port) + "\r\nContent-Length: 0\r\n\r\n")
                .status,
            405);
  // A body shorter than announced: refused, nothing stored.
  EXPECT_GE(testing::askRaw(port, "POST /api/label HTTP/1.1\r\nHost: 127.0.0.1:" +
                                      std::to_string(port) +
                                      "\r\nContent-Type: application/json\r\nContent-Length: 90"
                                      "\r\n\r\n{\"segment\": 1")
                .status,
            400);
  // A body that trickles in is cut off: one byte every 1.5 s gets a 408 (or a closed connection)
  // well before the 90 bytes it announced, so a slow client cannot hold a server thread.
  {
    const int fd = testing::connectTo(port);
    ASSERT_GE(fd, 0);
    const std::string head = "POST /api/label HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
                             "\r\nContent-Type: application/json\r\nContent-Length: 90\r\n\r\n";
    ASSERT_EQ(::send(fd, head.data(), head.size(), MSG_NOSIGNAL), static_cast<ssize_t>(head.size()));
    const auto start = std::chrono::steady_clock::now();
    std::string reply;
    for (int i = 0; i < 30 && reply.empty(); ++i) {
      if (::send(fd, " ", 1, MSG_NOSIGNAL) != 1) break;  // the server has closed it
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 1500) > 0) {
        char buffer[512];
        const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
        if (n <= 0) break;
        reply.assign(buffer, static_cast<std::size_t>(n));
      }
    }
    ::close(fd);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_LT(seconds, 20.0) << "the trickling body was not cut off";
    if (!reply.empty()) {
      EXPECT_EQ(reply.substr(0, 12), "HTTP/1.1 408") << reply;
    }
  }
  EXPECT_TRUE(catalogLabels(dir / "cat.sqlite").empty()) << "no refused request stored a label";

  // A good one is stored, with who and when; parameters and the case of the type do not matter.
  EXPECT_EQ(post(port, "/api/label", "[1]", "Application/JSON ; charset=utf-8").status, 400)
      << "past the type check";
  const Answer stored = post(port, "/api/label", label);
  ASSERT_EQ(stored.status, 200) << stored.body;
  EXPECT_EQ(jsonOf(stored)["by"], "tester");
  EXPECT_EQ(jsonOf(stored)["progress"]["objects"], 1);
  std::string by;
  EXPECT_EQ(catalogLabels(dir / "cat.sqlite", &by), (std::map<std::int64_t, int>{{id, 1}}));
  EXPECT_EQ(by, "tester");
  EXPECT_EQ(integrityOf(dir / "cat.sqlite"), "ok");
  view->signal(SIGINT);
  EXPECT_EQ(view->wait(10), 0);
}

TEST(ViewServer, UndoPutsTheLabelBackAndRefusesWhenAnotherTabChangedIt) {
  TempDir dir;
  const fs::path res = freshCopy(dir);
  int port = 0;
  auto view = startView(res, &port);
  ASSERT_GT(port, 0);
  const json segments = jsonOf(get(port, "/api/scenes/0/segments"));
  const std::string id = std::to_string(segments["segments"][1]["id"].get<std::int64_t>());
  const json first = jsonOf(post(port, "/api/label", R"({"segment": )" + id + R"(, "label": "not_object"})"));
  const json second = jsonOf(post(port, "/api/label", R"({"segment": )" + id + R"(, "label": "unsure", "by": "other tab"})"));
  ASSERT_TRUE(first.contains("event") && second.contains("event"));
  EXPECT_EQ(second["previous"], "not_object");
  // The first tab's undo comes too late: the other tab has changed the label since.
  const Answer late = post(port, "/api/undo", R"({"event": )" + first["event"].dump() + "}");
  EXPECT_EQ(late.status, 409) << late.body;
  // The other tab's own undo goes back to the first label.
  // Nobody undoes another's label: the first tab's undo of the other tab's event is refused.
  EXPECT_EQ(post(port, "/api/undo", R"({"event": )" + second["event"].dump() + "}").status, 409);
  const Answer undone = post(port, "/api/undo",
                             R"({"event": )" + second["event"].dump() + R"(, "by": "other tab"})");
  ASSERT_EQ(undone.status, 200) << undone.body;
  EXPECT_EQ(jsonOf(undone)["label"], "not_object");
  EXPECT_EQ(catalogLabels(dir / "cat.sqlite").at(std::stoll(id)), 0);
  // Cleared with null; the labels route shows what the catalog holds.
  ASSERT_EQ(post(port, "/api/label", R"({"segment": )" + id + R"(, "label": null})").status, 200);
  const json labels = jsonOf(get(port, "/api/scenes/0/labels"));
  EXPECT_EQ(labels["progress"]["labelled"], 0);
  EXPECT_TRUE(catalogLabels(dir / "cat.sqlite").empty());
  view->signal(SIGINT);
  EXPECT_EQ(view->wait(10), 0);
}

TEST(ViewServer, TwoViewersAndManyTabsLabellingAtOnceLoseNothing) {
  TempDir dir;
  const fs::path res = freshCopy(dir);
  int port_a = 0, port_b = 0;
  auto a = startView(res, &port_a);
  auto b = startView(res, &port_b);
  ASSERT_GT(port_a, 0);
  ASSERT_GT(port_b, 0);
  const json segments = jsonOf(get(port_a, "/api/scenes/0/segments"))["segments"];
  ASSERT_GE(segments.size(), 8u);
  // Four tabs (two on each viewer process) label the same 8 segments over and over.
  std::atomic<int> ok{0}, failed{0};
  std::vector<std::thread> tabs;
  for (int t = 0; t < 4; ++t) {
    tabs.emplace_back([&, t] {
      const int port = t % 2 == 0 ? port_a : port_b;
      for (int i = 0; i < 40; ++i) {
        const std::int64_t id = segments[static_cast<std::size_t>((i + t) % 8)]["id"];
        const char* label = (i + t) % 3 == 0 ? "object" : (i + t) % 3 == 1 ? "not_object" : "unsure";
        const Answer r = post(port, "/api/label",
                              R"({"segment": )" + std::to_string(id) + R"(, "label": ")" + label +
                                  R"(", "by": "tab )" + std::to_string(t) + "\"}");
        (r.status == 200 ? ok : failed)++;
      }
    });
  }
  for (std::thread& t : tabs) t.join();
  EXPECT_EQ(ok.load(), 160);
  EXPECT_EQ(failed.load(), 0);
  EXPECT_EQ(integrityOf(dir / "cat.sqlite"), "ok");
  discovery::Catalog catalog(dir / "cat.sqlite");
  const std::int64_t scene = catalog.scenes().at(0).id;
  const std::vector<discovery::LabelEvent> events = catalog.labelEvents(scene);
  EXPECT_EQ(events.size(), 160u) << "every label is one event";
  // Each segment's label is its last event's, and each event's "previous" is the label the one
  // before it on that segment left.
  std::map<std::int64_t, std::optional<int>> last;
  for (const discovery::LabelEvent& e : events) {
    EXPECT_EQ(e.previous, last[e.segment_id]) << "event " << e.id;
    last[e.segment_id] = e.label;
  }
  const std::map<std::int64_t, int> labels = catalogLabels(dir / "cat.sqlite");
  for (const auto& [segment, label] : last) EXPECT_EQ(labels.at(segment), label.value());
  EXPECT_EQ(catalog.labelCounts(scene).labelled, 8u);
  a->signal(SIGINT);
  b->signal(SIGINT);
  EXPECT_EQ(a->wait(10), 0);
  EXPECT_EQ(b->wait(10), 0);
}

TEST(ViewServer, SeveralScenesOfOneDiscoverRunAreEachShownAndLabelledApart) {
  TempDir dir;
  const fs::path& scan = scannedScene();
  // Two scenes, from a working directory elsewhere and a relative catalog path: the viewer
  // finds the catalog anyway (hypotheses.json notes it absolute).
  fs::copy_file(scan / "res" / "mesh.ply", dir / "desk.ply");
  writePly(dir / "mound.ply",
           testing::makeHeightField(120, 0.3f, [](float x, float y) {
             return 0.05f * std::max(0.0f, 1.0f - (x * x + y * y) / 0.01f);
           }));
  testing::ProcessOptions in_dir;
  in_dir.cwd = dir.path();
  ProcessResult r = testing::runProcess({OBJSCAN_EXE, "discover", "desk.ply", "mound.ply", "--catalog",
                                         "cat.sqlite", "--out", "both"},
                                        in_dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  int port = 0;
  auto view = startView(dir / "both", &port);
  ASSERT_GT(port, 0);
  const json results = jsonOf(get(port, "/api/results"));
  ASSERT_EQ(results["scenes"].size(), 2u) << results.dump();
  EXPECT_EQ(results["catalog"], (dir / "cat.sqlite").string());
  for (int i = 0; i < 2; ++i) {
    EXPECT_TRUE(results["scenes"][i]["labelling"].get<bool>()) << i;
    EXPECT_EQ(get(port, "/api/scenes/" + std::to_string(i) + "/mesh").status, 200);
  }
  const json desk = jsonOf(get(port, "/api/scenes/0/segments"));
  const json mound = jsonOf(get(port, "/api/scenes/1/segments"));
  ASSERT_FALSE(mound["segments"].empty());
  std::set<std::int64_t> desk_ids;
  for (const json& s : desk["segments"]) desk_ids.insert(s["id"].get<std::int64_t>());
  for (const json& s : mound["segments"]) EXPECT_EQ(desk_ids.count(s["id"].get<std::int64_t>()), 0u);
  const std::string id = mound["segments"][0]["id"].dump();
  ASSERT_EQ(post(port, "/api/label", R"({"segment": )" + id + R"(, "label": "object"})").status, 200);
  EXPECT_EQ(jsonOf(get(port, "/api/scenes/1/labels"))["progress"]["labelled"], 1);
  EXPECT_EQ(jsonOf(get(port, "/api/scenes/0/labels"))["progress"]["labelled"], 0);
  view->signal(SIGINT);
  EXPECT_EQ(view->wait(10), 0);
}

TEST(ViewServer, LabellerNamesThatAreNotNamesAreOneErrorLineAndNeverPrinted) {
  TempDir dir;  // the name is checked before the folder is read: no results needed
  const auto refused = [&](const std::vector<std::string>& env, const std::string& labeller,
                           const std::string& from) {
    std::vector<std::string> args = {OBJSCAN_EXE, "view", dir.path().string(), "--serve", "0"};
    if (!labeller.empty()) args.insert(args.end(), {"--labeller", labeller});
    testing::ProcessOptions options;
    options.env = env;
    const ProcessResult r = testing::runProcess(args, options);
    testing::expectOneErrorLine(r, 2, from + ": not a labeller's name");
    EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << "no escape reaches the terminal";
    EXPECT_EQ(r.err.find("\u202e"), std::string::npos);
  };
  refused({}, "a\x1b[31mred", "--labeller");
  refused({}, "\u202eevil", "--labeller");
  refused({}, "\u200b\u200b", "--labeller");
  refused({}, "\ufeffana", "--labeller");
  refused({"OBJSCAN_LABELLER=ana\x1b]0;title\x07"}, "", "$OBJSCAN_LABELLER");
  refused({"OBJSCAN_LABELLER=\u2066x\u2069"}, "", "$OBJSCAN_LABELLER");
  refused({"OBJSCAN_LABELLER=\u00a0\u3000"}, "", "$OBJSCAN_LABELLER");
}

TEST(ViewServer, FoldersWithoutResultsOrWithDamagedFilesSayWhat) {
  TempDir dir;
  fs::create_directories(dir / "empty");
  testing::expectOneErrorLine(objscan({"view", (dir / "empty").string(), "--serve", "0"}), 2,
                              "hypotheses.json: missing");
  testing::expectOneErrorLine(objscan({"view", (dir / "nowhere").string(), "--serve", "0"}), 2,
                              "nowhere");
  const fs::path res = freshCopy(dir);
  testing::expectOneErrorLine(objscan({"view", res.string(), "--serve", "70000"}), 2,
                              "the port must be a number");
  // Addresses a browser would read otherwise (010 is octal to it), or cannot reach.
  testing::expectOneErrorLine(objscan({"view", res.string(), "--serve", "127.0.0.010:0"}), 2,
                              "without leading zeros");
  testing::expectOneErrorLine(objscan({"view", res.string(), "--serve", "224.0.0.1:0"}), 2,
                              "multicast");
  // An empty file named as the catalog is not made a catalog: labelling is off, and it says why.
  testing::writeBytes(dir / "empty.sqlite", "");
  {
    int port = 0;
    auto view = startView(res, &port, {"--catalog", (dir / "empty.sqlite").string()});
    ASSERT_GT(port, 0);
    const json results = jsonOf(get(port, "/api/results"));
    EXPECT_NE(results.value("labelling_off", "").find("is empty"), std::string::npos)
        << results.dump();
    EXPECT_FALSE(results["scenes"][0]["labelling"].get<bool>());
    view->signal(SIGINT);
    EXPECT_EQ(view->wait(10), 0);
    EXPECT_NE(view->err().find("labelling is off"), std::string::npos) << view->err();
    EXPECT_EQ(fs::file_size(dir / "empty.sqlite"), 0u);
  }
  // A FIFO named as the catalog is neither "missing" nor opened (it would block).
  ASSERT_EQ(mkfifo((dir / "fifo").c_str(), 0600), 0);
  {
    int port = 0;
    auto view = startView(res, &port, {"--catalog", (dir / "fifo").string()});
    ASSERT_GT(port, 0);
    const json results = jsonOf(get(port, "/api/results"));
    EXPECT_NE(results.value("labelling_off", "").find("is not a regular file"), std::string::npos)
        << results.dump();
    view->signal(SIGINT);
    EXPECT_EQ(view->wait(10), 0);
    // No scene can be labelled, and the terminal does not say one is.
    EXPECT_NE(view->out().find("(1 can be shown, 0 can be labelled)"), std::string::npos)
        << view->out();
  }
  // A cut hypotheses.json: one error line naming it.
  fs::copy(res, dir / "cut", fs::copy_options::recursive);
  const std::string text = readWholeFile(res / "hypotheses.json");
  testing::writeBytes(dir / "cut" / "hypotheses.json", text.substr(0, text.size() / 2));
  testing::expectOneErrorLine(objscan({"view", (dir / "cut").string(), "--serve", "0"}), 2,
                              "hypotheses.json");
  // A damaged mesh, the folder's only scene: nothing to show, so one error line naming it and
  // exit 2 (not an empty page and exit 0).
  const std::string mesh = readWholeFile(res / "mesh.ply");
  testing::writeBytes(res / "mesh.ply", mesh.substr(0, mesh.size() / 3));
  const ProcessResult damaged =
      objscan({"view", res.string(), "--serve", "127.0.0.1:0", "--serve-wait", "60"});
  EXPECT_EQ(damaged.exit_code, 2) << damaged.out << damaged.err;
  // Besides the progress line: one error line, and no warning saying the same first.
  std::size_t errors = 0;
  for (const std::string& l : testing::lines(damaged.err)) {
    errors += l.rfind("objscan: error: ", 0) == 0 ? 1 : 0;
    EXPECT_EQ(l.find("warning"), std::string::npos) << l;
  }
  EXPECT_EQ(errors, 1u) << damaged.err;
  EXPECT_NE(damaged.err.find("no scene can be shown"), std::string::npos) << damaged.err;
  EXPECT_NE(damaged.err.find("mesh.ply"), std::string::npos) << damaged.err;
}

/// An organized PCD of a 64 x 48 pinhole view (f 60 px) of a floor 1 m away with a 20 cm box on
/// it, ASCII: what a depth camera's single view is saved as.
std::string pcdOfABoxOnAFloor() {
  constexpr int kWidth = 64, kHeight = 48;
  std::string text =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgba\nSIZE 4 4 4 4\nTYPE F F F U\n"
      "COUNT 1 1 1 1\nWIDTH 64\nHEIGHT 48\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3072\nDATA ascii\n";
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const bool box = std::abs(u - 32) < 10 && std::abs(v - 24) < 10;
      const float z = box ? 0.8f : 1.0f;
      char line[96];
      std::snprintf(line, sizeof line, "%.5f %.5f %.5f %u\n", (u - 31.5f) * z / 60.0f,
                    (v - 23.5f) * z / 60.0f, z, box ? 0xffc02020u : 0xff808080u);
      text += line;
    }
  }
  return text;
}

TEST(ViewServer, ShowsAndRendersDiscoverResultsOfAPcdViewAndOfAFrame) {
  TempDir dir;
  const fs::path& scan = scannedScene();
  testing::writeBytes(dir / "view.pcd", pcdOfABoxOnAFloor());
  const std::string catalog = (dir / "cat.sqlite").string();
  // info describes the PCD as discover reads it.
  const ProcessResult info = objscan({"info", (dir / "view.pcd").string()});
  EXPECT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("point cloud (PCD"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("3072, organized (64 x 48), 3072 with a reading; colours: yes"),
            std::string::npos)
      << info.out;
  ProcessResult r = objscan({"discover", (dir / "view.pcd").string(), "--catalog", catalog,
                             "--out", (dir / "pcd").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = objscan({"discover", (scan / "syn").string(), "--frame", "3", "--catalog", catalog, "--out",
               (dir / "frame").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* name : {"pcd", "frame"}) {
    SCOPED_TRACE(name);
    const fs::path res = dir / name;
    // Discover wrote the mesh it worked on, and noted it.
    const json hypotheses = json::parse(readWholeFile(res / "hypotheses.json"));
    ASSERT_EQ(hypotheses["scenes"][0].value("mesh_copy", ""), "scenes/scene_001.ply");
    EXPECT_EQ(readPly(res / "scenes" / "scene_001.ply").positions.size(),
              hypotheses["scenes"][0]["vertices"].get<std::size_t>());
    int port = 0;
    auto view = startView(res, &port);
    ASSERT_GT(port, 0);
    const json results = jsonOf(get(port, "/api/results"));
    EXPECT_FALSE(results["scenes"][0].contains("error")) << results.dump();
    // Found in the catalog by its source's hash, not the copy's: it can be labelled.
    EXPECT_TRUE(results["scenes"][0]["labelling"].get<bool>()) << results.dump();
    EXPECT_EQ(get(port, "/api/scenes/0/mesh").status, 200);
    view->signal(SIGINT);
    EXPECT_EQ(view->wait(10), 0);
    EXPECT_NE(view->out().find("1 can be shown, 1 can be labelled"), std::string::npos)
        << view->out();
    EXPECT_EQ(view->err().find("cannot be shown"), std::string::npos) << view->err();
    r = objscan({"render", res.string(), "--top", "1"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::is_regular_file(res / "renders" / "overview.png"));
  }
  // The copy removed: one error line naming it, exit 2, and what to do.
  fs::remove_all(dir / "pcd" / "scenes");
  const ProcessResult removed = objscan({"render", (dir / "pcd").string()});
  EXPECT_EQ(removed.exit_code, 2) << removed.err;
  EXPECT_NE(removed.err.find("view.pcd: is not a PLY file, and the copy of the mesh made from it, " +
                             (dir / "pcd" / "scenes" / "scene_001.ply").string() +
                             ", is missing: run objscan discover again"),
            std::string::npos)
      << removed.err;
  // A folder from before the copies were written: the same, saying so.
  json before = json::parse(readWholeFile(dir / "pcd" / "hypotheses.json"));
  before["scenes"][0].erase("mesh_copy");
  std::ofstream(dir / "pcd" / "hypotheses.json") << before.dump();
  const ProcessResult old = objscan({"render", (dir / "pcd").string()});
  EXPECT_EQ(old.exit_code, 2) << old.err;
  EXPECT_NE(old.err.find("view.pcd: is not a PLY file, and the results folder holds no copy"),
            std::string::npos)
      << old.err;
}

#else  // OBJSCAN_VIEW_PAGE_TEST

/// The page's pixels: how many differ from the empty background, and how many turned the
/// highlight's yellow since the last call (each call keeps the picture for the next).
struct CanvasPixels {
  int width = 0, height = 0, drawn = 0, turned_yellow = 0;
};

CanvasPixels canvasPixels(testing::ChromiumPage& page) {
  const json r = page.evaluate(R"((function () {
    var c = document.querySelector('#view canvas');
    if (!c) return null;
    var t = document.createElement('canvas');
    t.width = c.width; t.height = c.height;
    var g = t.getContext('2d');
    g.drawImage(c, 0, 0);
    var d = g.getImageData(0, 0, t.width, t.height).data, drawn = 0, turned = 0;
    var before = window.__pixels && window.__pixels.length === d.length ? window.__pixels : null;
    for (var i = 0; i < d.length; i += 4) {
      if (Math.abs(d[i] - 244) + Math.abs(d[i + 1] - 245) + Math.abs(d[i + 2] - 247) > 24) ++drawn;
      // The highlight is (255, 215, 0) lit by white light: blue stays near 0, green near 0.84 red.
      var yellow = d[i] > 90 && d[i + 1] > 0.7 * d[i] && d[i + 1] < 0.95 * d[i] && d[i + 2] < 0.2 * d[i];
      var changed = before && Math.abs(d[i] - before[i]) + Math.abs(d[i + 1] - before[i + 1]) +
                                  Math.abs(d[i + 2] - before[i + 2]) > 30;
      if (yellow && changed) ++turned;
    }
    window.__pixels = d;
    return {width: t.width, height: t.height, drawn: drawn, turned: turned};
  })())");
  CanvasPixels p;
  if (!r.is_object()) return p;
  p.width = r["width"];
  p.height = r["height"];
  p.drawn = r["drawn"];
  p.turned_yellow = r["turned"];
  return p;
}

/// The centre of an element, in page coordinates.
std::pair<double, double> centreOf(testing::ChromiumPage& page, const std::string& selector) {
  const json r = page.evaluate("(function () { var e = document.querySelector('" + selector +
                               "'); if (!e) return null; e.scrollIntoView({block: 'center'});"
                               " var b = e.getBoundingClientRect();"
                               " return [b.left + b.width / 2, b.top + b.height / 2]; })()");
  EXPECT_TRUE(r.is_array()) << selector;
  return r.is_array() ? std::make_pair(r[0].get<double>(), r[1].get<double>())
                      : std::make_pair(0.0, 0.0);
}

TEST(ViewPage, DrawsSelectsAndLabelsInChromiumAndTrainUsesTheLabels) {
  TempDir dir;
  const fs::path res = freshCopy(dir);
  int port = 0;
  auto view = startView(res, &port);
  ASSERT_GT(port, 0);
  testing::ChromiumPage page;
  ASSERT_TRUE(page.ok());
  page.navigate("http://127.0.0.1:" + std::to_string(port) + "/");
  ASSERT_TRUE(page.waitFor("document.body.getAttribute('data-state') === 'ready'", 60))
      << page.evaluate("document.body.outerHTML").dump() << page.console();

  // The canvas shows the scene: most of it is mesh, not background.
  const CanvasPixels shown = canvasPixels(page);
  ASSERT_GT(shown.width, 400);
  EXPECT_GT(shown.drawn, shown.width * shown.height / 5) << "the canvas is (nearly) blank";

  // A click on a row of the ranking selects that hypothesis: row, details, download, and the
  // camera turned to it, drawn in the highlight (the largest of the first five, so that it is
  // surely seen).
  const int rank = page.evaluate("sceneHypotheses().slice(0, 5).reduce(function (a, b) {"
                                 " return b.vertex_count > a.vertex_count ? b : a; }).rank")
                       .get<int>();
  const std::string chosen = std::to_string(rank);
  auto [rx, ry] = centreOf(page, "#ranking tr[data-rank=\"" + chosen + "\"]");
  page.click(rx, ry);
  ASSERT_TRUE(
      page.waitFor("document.body.getAttribute('data-selected') === 'rank:" + chosen + "'", 10));
  EXPECT_EQ(page.evaluate("document.querySelector('#ranking tr.selected').getAttribute('data-rank')"),
            chosen);
  char file[64];
  std::snprintf(file, sizeof file, "/results/objects/rank_%03d.ply", rank);
  EXPECT_EQ(page.evaluate("document.getElementById('download').getAttribute('href')"), file);
  ASSERT_TRUE(
      page.waitFor("document.body.getAttribute('data-highlight') === 'rank:" + chosen + "'", 10));
  EXPECT_GT(canvasPixels(page).turned_yellow, 30) << "the selected hypothesis is not highlighted";

  // A click on the mesh where another hypothesis is drawn selects that one: a point of it is
  // found by projecting its vertices and checking with the page's own picking, then clicked for
  // real. The point is a whole pixel, the page's element there is the canvas, and the picking
  // gives the same hypothesis two pixels around it, so that the browser's rounding of the
  // pointer's position cannot move the click onto a neighbour.
  const json point = page.evaluate(R"((function () {
    var v = state.view, m = v.mesh, box = v.renderer.domElement.getBoundingClientRect(), tries = 0;
    function rankAt(x, y) { var hit = v.pick(x, y); return hit >= 0 ? m.ranks[hit] : -1; }
    for (var i = 0; i < m.vertices && tries < 300; i += 3) {
      var rank = m.ranks[i];
      if (rank === 0 || rank === state.selectedRank) continue;
      var p = new THREE.Vector3(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
      p.project(v.camera);
      var x = Math.round(box.left + (p.x + 1) / 2 * box.width);
      var y = Math.round(box.top + (1 - p.y) / 2 * box.height);
      if (p.z > 1 || x < box.left + 4 || y < box.top + 4 || x > box.right - 4 || y > box.bottom - 4) continue;
      if (document.elementFromPoint(x, y) !== v.renderer.domElement) continue;
      ++tries;
      var around = [[0, 0], [-2, 0], [2, 0], [0, -2], [0, 2], [-2, -2], [2, 2], [-2, 2], [2, -2]];
      if (around.every(function (d) { return rankAt(x + d[0], y + d[1]) === rank; })) return [x, y, rank];
    }
    return null;
  })())");
  ASSERT_TRUE(point.is_array()) << "no other hypothesis is visible";
  page.click(point[0].get<double>(), point[1].get<double>());
  EXPECT_TRUE(page.waitFor("document.body.getAttribute('data-selected') === 'rank:" +
                               point[2].dump() + "'",
                           10))
      << page.evaluate("document.body.getAttribute('data-selected')").dump();

  // Labelling with the keyboard, as the paper's annotate tool: each candidate judged against the
  // ground truth (object at IoU >= 0.5 with a true object, not one below 0.2, unsure between),
  // until at least six of each are labelled.
  const fs::path catalog_path = dir / "cat.sqlite";
  std::map<std::int64_t, double> best_iou;
  {
    discovery::Catalog catalog(catalog_path);
    const TriangleMesh mesh = readPly(res / "mesh.ply");
    const discovery::GroundTruthObjects truth(
        discovery::truthFromMesh(scannedScene() / "syn" / "scene_gt.ply", mesh));
    for (const discovery::CatalogSegment& s : catalog.segments(catalog.scenes().at(0).id, true)) {
      best_iou[s.id] = truth.bestMatch(s.vertices).iou;
    }
  }
  page.key("l");
  ASSERT_TRUE(page.waitFor("state.mode === 'label' && state.current === 0", 10));
  std::map<std::int64_t, int> pressed;  // segment -> label typed
  std::int64_t last = 0;                // the segment labelled last
  int objects = 0, others = 0, labelled = 0;
  for (int step = 0; step < static_cast<int>(best_iou.size()) && (objects < 6 || others < 6);
       ++step) {
    const std::int64_t id = page.evaluate("state.segments[state.current].id").get<std::int64_t>();
    const double iou = best_iou.at(id);
    const bool object = iou >= 0.5, other = iou < 0.2;
    if ((object && objects >= 6) || (other && others >= 6)) {
      page.key("j");
      ASSERT_TRUE(page.waitFor("state.segments[state.current].id !== " + std::to_string(id), 10));
      continue;
    }
    page.key(object ? "y" : other ? "n" : "u");
    ++labelled;
    ASSERT_TRUE(page.waitFor("document.body.getAttribute('data-labelled') === '" +
                                 std::to_string(labelled) + "'",
                             10))
        << "label " << labelled << " did not arrive; " << page.console();
    pressed[id] = object ? 1 : other ? 0 : 2;
    last = id;
    objects += object;
    others += other;
  }
  std::size_t available = 0;
  for (const auto& [segment, iou] : best_iou) available += iou >= 0.5 ? 1 : 0;
  ASSERT_GE(objects, 6) << "the scene has too few object candidates for this test: " << available
                        << " of " << best_iou.size() << " at IoU >= 0.5";
  ASSERT_GE(others, 6);
  std::string by;
  EXPECT_EQ(catalogLabels(catalog_path, &by), pressed) << "the catalog holds what was typed";
  EXPECT_EQ(by, "tester");
  EXPECT_EQ(page.evaluate("document.getElementById('progress').textContent"),
            std::to_string(labelled) + " / " + std::to_string(best_iou.size()) + " labelled");

  // z undoes the last label (the catalog forgets it), and it is made again.
  page.key("z");
  ASSERT_TRUE(page.waitFor("!state.busy && document.body.getAttribute('data-labelled') === '" +
                               std::to_string(labelled - 1) + "'",
                           10));
  EXPECT_EQ(catalogLabels(catalog_path).count(last), 0u);
  page.key(pressed[last] == 1 ? "y" : pressed[last] == 0 ? "n" : "u");
  ASSERT_TRUE(page.waitFor("document.body.getAttribute('data-labelled') === '" +
                               std::to_string(labelled) + "'",
                           10));
  EXPECT_EQ(catalogLabels(catalog_path), pressed);

  // train on the catalog's labels, then discover with the model.
  ProcessResult r = objscan({"train", "--catalog", catalog_path.string(), "--model",
                             (dir / "model.yml").string()});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  r = objscan({"discover", (res / "mesh.ply").string(), "--catalog", catalog_path.string(),
               "--model", (dir / "model.yml").string(), "--out", (dir / "ranked").string()});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const json ranked = json::parse(readWholeFile(dir / "ranked" / "hypotheses.json"));
  EXPECT_EQ(ranked["scoring"]["kind"], "rbf_svm");
  EXPECT_FALSE(ranked["hypotheses"].empty());
  view->signal(SIGINT);
  EXPECT_EQ(view->wait(10), 0);
}

TEST(ViewPage, ADamagedMeshIsSaidInThePage) {
  // Two scenes, the second damaged after discover: the viewer serves the first, and the page says
  // why the second cannot be shown when it is picked (a folder with no scene to show is an error, exit 2).
  TempDir dir;
  const fs::path& scan = scannedScene();
  fs::copy_file(scan / "res" / "mesh.ply", dir / "desk.ply");
  writePly(dir / "mound.ply", testing::makeHeightField(120, 0.3f, [](float x, float y) {
             return 0.05f * std::max(0.0f, 1.0f - (x * x + y * y) / 0.01f);
           }));
  const ProcessResult r = objscan({"discover", (dir / "desk.ply").string(),
                                   (dir / "mound.ply").string(), "--no-catalog", "--out",
                                   (dir / "res").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string mesh = readWholeFile(dir / "mound.ply");
  testing::writeBytes(dir / "mound.ply", mesh.substr(0, mesh.size() / 3));
  const fs::path res = dir / "res";
  int port = 0;
  auto view = startView(res, &port);
  ASSERT_GT(port, 0);
  testing::ChromiumPage page;
  ASSERT_TRUE(page.ok());
  page.navigate("http://127.0.0.1:" + std::to_string(port) + "/");
  ASSERT_TRUE(page.waitFor("document.body.getAttribute('data-state') === 'ready'", 60));
  EXPECT_NE(page.evaluate("document.getElementById('scene').options[1].textContent")
                .get<std::string>()
                .find("(cannot be shown)"),
            std::string::npos);
  page.evaluate(
      "(function () { var s = document.getElementById('scene'); s.value = '1';"
      " s.dispatchEvent(new Event('change')); return true; })()");
  ASSERT_TRUE(page.waitFor("document.body.getAttribute('data-state') === 'error'", 30));
  const std::string shown = page.evaluate("document.getElementById('message').textContent");
  EXPECT_NE(shown.find("cannot be shown"), std::string::npos) << shown;
  EXPECT_NE(shown.find("mound.ply"), std::string::npos) << shown;
  view->signal(SIGINT);
  EXPECT_EQ(view->wait(10), 0);
}

TEST(ViewPage, AGlbObjectStandsUpInThreeJsGltfLoader) {
  // glTF is Y-up. A mound on a z-up table, exported as GLB and loaded by three.js's own glTF
  // reader (Debian's libjs-three): its height must come out along +Y, top up.
  TempDir dir;
  writePly(dir / "mound.ply", testing::makeHeightField(120, 0.3f, [](float x, float y) {
             return 0.05f * std::max(0.0f, 1.0f - (x * x + y * y) / 0.01f);
           }));
  const ProcessResult r = objscan({"discover", (dir / "mound.ply").string(), "--no-catalog",
                                   "--object-format", "glb", "--out", (dir / "res").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const TriangleMesh scene = readPly(dir / "mound.ply");
  const json first = json::parse(readWholeFile(dir / "res" / "hypotheses.json"))["hypotheses"][0];
  float low = INFINITY, high = -INFINITY;
  for (const std::int32_t v : first["vertices"].get<std::vector<std::int32_t>>()) {
    low = std::min(low, scene.positions[static_cast<std::size_t>(v)].z());
    high = std::max(high, scene.positions[static_cast<std::size_t>(v)].z());
  }
  ASSERT_GT(high - low, 0.01f);  // the mound's rise, in metres
  const std::string glb = readWholeFile(dir / "res" / first["file"].get<std::string>());
  std::string bytes;
  for (const char c : glb) bytes += std::to_string(static_cast<unsigned char>(c)) + ",";
  const std::string three = "/usr/share/javascript/three/";
  testing::writeBytes(
      dir / "page.html",
      "<!doctype html><script src=\"" + testing::fileUrl(three + "three.min.js") +
          "\"></script><script src=\"" +
          testing::fileUrl(three + "examples/js/loaders/GLTFLoader.js") +
          "\"></script><script>var GLB = new Uint8Array([" + bytes + "]);</script>");
  testing::ChromiumPage page;
  ASSERT_TRUE(page.ok());
  page.navigate(testing::fileUrl(dir / "page.html"));
  const json box = page.evaluate(R"(new Promise(function (done) {
    new THREE.GLTFLoader().parse(GLB.buffer, '', function (gltf) {
      gltf.scene.updateMatrixWorld(true);
      var b = new THREE.Box3().setFromObject(gltf.scene);
      done({min: [b.min.x, b.min.y, b.min.z], max: [b.max.x, b.max.y, b.max.z]});
    }, function (e) { done({error: String(e)}); });
  }))");
  ASSERT_TRUE(box.contains("min")) << box.dump() << page.console();
  // In three.js's world (Y up) the mound rises along +Y from its rim to its top, as on the table.
  EXPECT_NEAR(box["min"][1].get<float>(), low, 1e-4f) << box.dump();
  EXPECT_NEAR(box["max"][1].get<float>(), high, 1e-4f) << box.dump();
}

TEST(ViewPage, TheReportsInlineViewDrawsOfflineAndLinksTheViewerWhenServed) {
  TempDir dir;
  const fs::path res = freshCopy(dir);
  testing::ChromiumPage page;
  ASSERT_TRUE(page.ok());
  // Opened from disk, no server: the scene in 3-D from the page alone.
  page.navigate(testing::fileUrl(fs::absolute(res / "report.html")));
  ASSERT_TRUE(page.waitFor("document.getElementById('mesh-view').getAttribute('data-state') !== "
                           "'loading'",
                           30));
  EXPECT_EQ(page.evaluate("document.getElementById('mesh-view').getAttribute('data-state')"),
            "ready")
      << page.evaluate("document.getElementById('mesh-view').textContent").dump();
  const json drawn = page.evaluate(R"((function () {
    var c = document.querySelector('#mesh-view canvas');
    var t = document.createElement('canvas');
    t.width = c.width; t.height = c.height;
    var g = t.getContext('2d');
    g.drawImage(c, 0, 0);
    var d = g.getImageData(0, 0, t.width, t.height).data, n = 0;
    for (var i = 0; i < d.length; i += 4) {
      if (Math.abs(d[i] - 244) + Math.abs(d[i + 1] - 245) + Math.abs(d[i + 2] - 247) > 24) ++n;
    }
    return n / (t.width * t.height);
  })())");
  ASSERT_TRUE(drawn.is_number());
  // The whole scene in a 480-pixel band: about an eighth of it is mesh on this desk.
  EXPECT_GT(drawn.get<double>(), 0.05) << "the inline view is (nearly) blank";
  EXPECT_EQ(page.evaluate("document.body.getAttribute('data-errors')"), "0") << page.console();
  EXPECT_EQ(page.evaluate("document.querySelector('#viewer-link a') === null"), true);
  // The best five painted, as the pictures paint them (scan's default --top, five close-ups),
  // rank 1 in the palette's red; the rest (about 460 on a fused desk) only when asked.
  const std::string paint = R"((function (all) {
    var v = document.getElementById('mesh-view').meshView, m = v.mesh, box = document.getElementById('mesh-all');
    if (box.checked !== all) box.click();
    var out = {top: document.getElementById('mesh-view').getAttribute('data-paint-top'),
               painted: {}, unpainted: 0, red: 0, ones: 0};
    for (var i = 0; i < m.vertices; ++i) {
      var r = m.ranks[i];
      if (r === 0) continue;
      if (v.painted(r)) out.painted[r] = true; else ++out.unpainted;
      if (r === 1) {
        ++out.ones;
        var c = v.colourArray;  // 65 % of the palette's red over the vertex colour
        if (c[3 * i] > c[3 * i + 1] && c[3 * i] > c[3 * i + 2]) ++out.red;
      }
    }
    out.painted = Object.keys(out.painted).length;
    return out;
  }))";
  const json top = page.evaluate(paint + "(false)");
  EXPECT_EQ(top["top"], "5") << top.dump();
  EXPECT_EQ(top["painted"], 5) << top.dump();
  EXPECT_GT(top["unpainted"].get<int>(), 0) << top.dump();
  EXPECT_GT(top["ones"].get<int>(), 0) << top.dump();
  EXPECT_EQ(top["red"], top["ones"]) << top.dump();
  const json all = page.evaluate(paint + "(true)");
  EXPECT_EQ(all["unpainted"], 0) << all.dump();
  EXPECT_GT(all["painted"].get<int>(), 5) << all.dump();

  // Served by objscan view, the same report links the viewer.
  int port = 0;
  auto view = startView(res, &port);
  ASSERT_GT(port, 0);
  page.navigate("http://127.0.0.1:" + std::to_string(port) + "/results/report.html");
  EXPECT_TRUE(page.waitFor("document.querySelector('#viewer-link a') !== null", 30));
  EXPECT_EQ(page.evaluate("document.querySelector('#viewer-link a').getAttribute('href')"), "/");
  view->signal(SIGINT);
  EXPECT_EQ(view->wait(10), 0);
}

// objscan batch's collection page (index.html), opened from disk: every scene with its objects,
// every picture decoded, objects across scenes from other scenes only, nearest first; and its
// links open the viewer of the collection on that scene and that object.
TEST(ViewPage, TheCollectionPageShowsTheScenesAndItsLinksOpenTheirObjectsInTheViewer) {
  TempDir dir;
  const fs::path out = dir / "all";
  const testing::ProcessResult batch =
      testing::objscan({"batch", "synth:3,frames=8,objects=3", "synth:4,frames=8,objects=3",
                        "synth:5,frames=8,objects=3", "--out", out.string(), "--jobs", "2", "--",
                        "--no-ground-truth"});
  ASSERT_EQ(batch.exit_code, 0) << batch.out << batch.err;
  testing::ChromiumPage page;
  ASSERT_TRUE(page.ok());
  page.navigate("file://" + (out / "index.html").string());
  ASSERT_TRUE(page.waitFor("document.body.dataset.images !== undefined", 30)) << page.console();
  const std::string images = page.evaluate("document.body.dataset.images").get<std::string>();
  const std::size_t slash = images.find('/');
  ASSERT_NE(slash, std::string::npos);
  EXPECT_EQ(images.substr(0, slash), images.substr(slash + 1)) << "pictures that did not decode";
  EXPECT_GT(std::stoi(images.substr(slash + 1)), 10);
  EXPECT_EQ(page.evaluate("document.body.dataset.errors"), "0") << page.console();
  EXPECT_EQ(page.evaluate("document.querySelectorAll('section.scene').length"), 3);
  EXPECT_EQ(page.evaluate("document.querySelectorAll('section.scene figure').length"),
            page.evaluate("document.querySelectorAll('section.scene figure img').length"));
  // Each group: a query and its neighbours, none from the query's scene, nearest first.
  const json groups = page.evaluate(R"((function () {
    return Array.prototype.map.call(document.querySelectorAll('section.group'), function (g) {
      var q = g.querySelector('figure.query');
      return {scene: q.dataset.scene, neighbours: Array.prototype.map.call(
        g.querySelectorAll('figure.neighbour'), function (n) {
          return {scene: n.dataset.scene, distance: Number(n.dataset.distance),
                  href: n.querySelector('a').getAttribute('href')};
        })};
    });
  })())");
  ASSERT_TRUE(groups.is_array());
  ASSERT_GE(groups.size(), 1u);
  std::string link;
  std::size_t neighbours = 0;
  for (const json& g : groups) {
    double last = 0.0;
    for (const json& n : g["neighbours"]) {
      EXPECT_NE(n["scene"], g["scene"]);
      EXPECT_GE(n["distance"].get<double>(), last);
      last = n["distance"].get<double>();
      ++neighbours;
      const std::string href = n["href"];
      // One on a scene other than the first, which the viewer shows unasked.
      if (link.empty() && href.find("#scene=0&") == std::string::npos) link = href;
    }
  }
  EXPECT_GT(neighbours, 0u);
  ASSERT_FALSE(link.empty()) << groups.dump();
  // The link names the viewer's default address; the viewer here listens on a free port.
  const std::string prefix = "http://127.0.0.1:8090/#scene=";
  ASSERT_EQ(link.rfind(prefix, 0), 0u) << link;
  // #scene=I&rank=N selects hypothesis N; #scene=I&segment=ID puts segment ID up for labelling.
  const std::string hash = link.substr(link.find('#'));
  const std::size_t amp = hash.find('&'), equals = hash.find('=', amp);
  const std::string scene = hash.substr(7, amp - 7);
  const std::string selected =
      hash.substr(amp + 1, equals - amp - 1) + ":" + hash.substr(equals + 1);
  ASSERT_TRUE(selected.rfind("rank:", 0) == 0 || selected.rfind("segment:", 0) == 0) << hash;
  int port = 0;
  auto view = startView(out / "collection", &port);
  ASSERT_GT(port, 0);
  page.navigate("http://127.0.0.1:" + std::to_string(port) + "/" + hash);
  EXPECT_TRUE(
      page.waitFor("document.body.getAttribute('data-selected') === '" + selected + "'", 60))
      << page.evaluate("document.body.getAttribute('data-selected')").dump() << page.console();
  EXPECT_EQ(page.evaluate("String(state.scene)"), scene);
  EXPECT_EQ(page.evaluate("document.getElementById('scene').value"), scene);
}

#endif  // OBJSCAN_VIEW_PAGE_TEST

}  // namespace
}  // namespace objscan
