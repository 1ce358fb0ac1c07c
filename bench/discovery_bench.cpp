// Per-scene discovery speed: discoverObjects on one mesh, each stage's time next to the paper's
// single-threaded table (Karpathy et al. 2013, section V: seconds per scene of ~200k vertices).
//
//   discovery_bench <mesh.ply> [--repeat N] [--catalog-segments N] [--json FILE]
//
// Recurrence is timed against an SQLite catalog of --catalog-segments segments (default 100,000;
// 0 skips it) in 1,000 other scenes, made in a temporary folder from this scene's candidates
// with their extents scaled by 0.5-2x and their measures jittered (seeded), so the window and
// the neighbours look like a real catalog's. The row is what `objscan discover` does per scene:
// read every segment's extents and measures from the catalog, build the kd-tree, and look up
// each candidate's 10 most similar.
//
// The mesh is read once (with normals: a fused scene has them), as `objscan discover` reads it:
// with the camera's up from the trajectory.txt beside it, when there is one (the context and the
// things on level tops use it); discoverObjects then runs N times
// (default 3) and every figure is the median over the runs. Wall time is what a user waits for;
// CPU time is summed over all threads, which is what the paper's single-threaded seconds compare
// with. A measure's CPU time is its thread time summed over the distinct candidates, with the
// per-scene look-up it needs (see DiscoveryTimings). Peak memory is the kernel's high-water mark
// of the resident set above the loaded mesh (reset after loading).

#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <random>

#include <nlohmann/json.hpp>

#include "bench_main.h"
#include "bench_memory.h"
#include "objscan/core/atomic_file.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/discover.h"
#include "objscan/discovery/scenes.h"

namespace {

using Json = nlohmann::json;
using objscan::bench::resetPeakMemory;
using objscan::bench::statusBytes;
using objscan::discovery::DiscoveryTimings;

double median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  const std::size_t n = x.size();
  return n % 2 == 1 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

/// One row of the table: what it is, how to read it from a run, and the paper's seconds (< 0:
/// the paper has no such row).
struct Row {
  const char* name;
  std::function<double(const DiscoveryTimings&)> wall_ms;  ///< empty: no wall time of its own
  std::function<double(const DiscoveryTimings&)> cpu_ms;
  const char* key;
  double paper_s;
  const char* paper_name;
};

std::string cell(double x, const char* format) {
  if (x < 0.0) return "-";
  char text[32];
  std::snprintf(text, sizeof text, format, x);
  return text;
}

constexpr const char* kUsage =
    "usage: discovery_bench <mesh.ply> [--repeat N] [--catalog-segments N] [--json FILE]";

/// Milliseconds `f` takes.
double timeMs(const std::function<void()>& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

struct RecurrenceTiming {
  double load_ms = -1, index_ms = -1, query_ms = -1, total_ms = -1;
  std::size_t lookups = 0;  ///< the scene's distinct candidates
  std::size_t found = 0;    ///< candidates with at least one similar segment in the window
};

/// See the header comment.
RecurrenceTiming timeRecurrence(const objscan::discovery::SceneCandidates& scene,
                                const objscan::discovery::DiscoveryConfig& config, long segments) {
  namespace d = objscan::discovery;
  RecurrenceTiming r;
  if (segments <= 0 || scene.segments.empty()) return r;
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("discovery_bench_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  struct Cleanup {
    std::filesystem::path dir;
    ~Cleanup() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } cleanup{dir};
  {
    d::Catalog catalog(dir / "catalog.sqlite");
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> size(0.5f, 2.0f);
    std::normal_distribution<double> jitter(0.0, 0.1);
    const long scenes = 1000, per_scene = std::max(1L, segments / scenes);
    for (long s = 0; s < scenes; ++s) {
      std::vector<d::CatalogSegment> rows;
      for (long i = 0; i < per_scene; ++i) {
        const std::size_t from = rng() % scene.segments.size();
        d::CatalogSegment c;
        c.extents = scene.segments[from].extents * size(rng);
        c.measures = scene.measures[from];
        for (double* m : {&c.measures.compactness, &c.measures.symmetry, &c.measures.smoothness,
                          &c.measures.local_convexity, &c.measures.global_convexity}) {
          *m *= 1.0 + jitter(rng);
        }
        c.vertices = {0};
        rows.push_back(c);
      }
      d::CatalogScene entry;
      entry.name = "bench scene " + std::to_string(s);
      entry.content_hash = std::to_string(s);
      entry.settings = "bench";
      catalog.addScene(entry, rows);
    }
  }
  d::SceneCandidates query = scene;
  r.total_ms = timeMs([&] {
    const d::Catalog catalog(dir / "catalog.sqlite");
    std::vector<d::RecurrenceEntry> entries;
    r.load_ms = timeMs([&] { entries = catalog.recurrenceEntries(); });
    std::optional<d::RecurrenceIndex> index;
    r.index_ms = timeMs([&] { index.emplace(std::move(entries)); });
    r.query_ms = timeMs([&] { d::addRecurrence(query, *index, -1, config); });
  });
  r.lookups = query.measures.size();
  for (const d::ShapeMeasures& m : query.measures) r.found += std::isfinite(m.recurrence);
  return r;
}

int run(int argc, char** argv) {
  std::string mesh_path, json_path;
  int repeat = 3;
  long catalog_segments = 100000;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--repeat" && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (flag == "--catalog-segments" && i + 1 < argc) {
      catalog_segments = std::max(0L, std::atol(argv[++i]));
    } else if (flag == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else if (!flag.empty() && flag[0] != '-' && mesh_path.empty()) {
      mesh_path = flag;
    } else {
      throw std::invalid_argument(kUsage);
    }
  }
  if (mesh_path.empty()) throw std::invalid_argument(kUsage);
  objscan::discovery::SceneReading reading;
  reading.hash = false;
  objscan::discovery::SceneInput scene = objscan::discovery::loadScene(mesh_path, reading);
  const objscan::TriangleMesh mesh = std::move(scene.mesh);
  malloc_trim(0);
  const double baseline = statusBytes("VmRSS");
  const bool peak_measurable = resetPeakMemory();

  objscan::discovery::DiscoveryConfig config;
  config.objects.context.view_up = scene.view_up;
  std::vector<DiscoveryTimings> runs;
  std::size_t hypotheses = 0;
  for (int r = 0; r < repeat; ++r) {
    DiscoveryTimings t;
    hypotheses = objscan::discovery::discoverObjects(mesh, config, &t).size();
    runs.push_back(t);
  }
  const double peak_mb = peak_measurable ? (statusBytes("VmHWM") - baseline) / 1e6 : -1.0;
  const RecurrenceTiming recurrence =
      timeRecurrence(objscan::discovery::findCandidates(mesh, config), config, catalog_segments);

  using T = DiscoveryTimings;
  const auto measure = [](std::size_t k) {
    return [k](const T& t) { return t.per_measure_cpu_ms[k]; };
  };
  const std::vector<Row> rows = {
      {"mesh graph (edges, Eq. 1)", [](const T& t) { return t.graph_ms; },
       [](const T& t) { return t.graph_cpu_ms; }, "graph", -1.0, ""},
      {"support planes (objscan's)", [](const T& t) { return t.support_ms; },
       [](const T& t) { return t.support_cpu_ms; }, "supports", -1.0, ""},
      {"segmentation, all scales", [](const T& t) { return t.segment_ms; },
       [](const T& t) { return t.segment_cpu_ms; }, "segmentation", 1.5, "over-segmentation"},
      {"candidates + hard filters", [](const T& t) { return t.filter_ms; },
       [](const T& t) { return t.filter_cpu_ms; }, "filter", -1.0, ""},
      {"  compactness", nullptr, measure(0), "compactness", 0.1, "compactness"},
      {"  symmetry", nullptr, measure(1), "symmetry", 3.8, "symmetry"},
      {"  smoothness", nullptr, measure(2), "smoothness", 2.5, "smoothness"},
      {"  local convexity", nullptr, measure(3), "local_convexity", 1.3, "local convexity"},
      {"  global convexity", nullptr, measure(4), "global_convexity", 13.3, "global convexity"},
      {"measures", [](const T& t) { return t.measure_ms; },
       [](const T& t) { return t.measure_cpu_ms; }, "measures", -1.0, ""},
      {"scores + suppression", [](const T& t) { return t.suppress_ms; },
       [](const T& t) { return t.suppress_cpu_ms; }, "suppression", -1.0, ""},
      {"recurrence vs the catalog", [&](const T&) { return recurrence.total_ms; }, nullptr,
       "recurrence", 0.1, "recurrence"},
      {"total",
       [](const T& t) {
         return t.graph_ms + t.support_ms + t.segment_ms + t.filter_ms + t.measure_ms +
                t.suppress_ms;
       },
       [](const T& t) {
         return t.graph_cpu_ms + t.support_cpu_ms + t.segment_cpu_ms + t.filter_cpu_ms +
                t.measure_cpu_ms + t.suppress_cpu_ms;
       },
       "total", 25.0, "total"},
  };

  std::printf("discovery: %s, %zu vertices, %zu triangles, %d run(s), medians\n", mesh_path.c_str(),
              mesh.positions.size(), mesh.triangles.size(), repeat);
  std::printf("  camera's up: %s\n", scene.view_up ? "from the trajectory.txt beside the mesh"
                                                    : "none (no trajectory.txt beside the mesh)");
  std::printf("  %zu candidates, %zu hypotheses; peak memory above the mesh %s MB\n",
              runs.back().candidate_count, hypotheses, cell(peak_mb, "%.0f").c_str());
  std::printf("  %-32s %10s %10s %12s   %s\n", "stage", "wall ms", "CPU ms", "paper s", "");
  Json stages = Json::object();
  for (const Row& row : rows) {
    const auto over = [&](const std::function<double(const T&)>& f) {
      if (!f) return -1.0;
      std::vector<double> x;
      for (const T& t : runs) x.push_back(f(t));
      return median(x);
    };
    const double wall = over(row.wall_ms), cpu = over(row.cpu_ms);
    std::printf("  %-32s %10s %10s %12s   %s\n", row.name, cell(wall, "%.0f").c_str(),
                cell(cpu, "%.0f").c_str(), cell(row.paper_s, "%.1f").c_str(), row.paper_name);
    stages[row.key] = {{"wall_ms", wall >= 0.0 ? Json(wall) : Json()},
                       {"cpu_ms", cpu >= 0.0 ? Json(cpu) : Json()},
                       {"paper_s", row.paper_s >= 0.0 ? Json(row.paper_s) : Json()}};
  }
  if (recurrence.total_ms >= 0.0) {
    std::printf(
        "  recurrence: %ld catalog segments in 1000 scenes: read %.0f ms, kd-tree %.0f ms, "
        "%zu look-ups %.1f ms (%zu with similar segments); not in the total\n",
        catalog_segments, recurrence.load_ms, recurrence.index_ms, recurrence.lookups,
        recurrence.query_ms, recurrence.found);
  }
  std::printf(
      "  (paper: single-threaded seconds for a ~200k-vertex scene; CPU ms is the comparable "
      "figure)\n");
  if (!json_path.empty()) {
    const Json j = {{"mesh", mesh_path},
                    {"vertices", mesh.positions.size()},
                    {"triangles", mesh.triangles.size()},
                    {"repeat", repeat},
                    {"candidates", runs.back().candidate_count},
                    {"hypotheses", hypotheses},
                    {"peak_mb_above_mesh", peak_mb >= 0.0 ? Json(peak_mb) : Json()},
                    {"recurrence",
                     {{"catalog_segments", catalog_segments},
                      {"read_ms", recurrence.load_ms},
                      {"index_ms", recurrence.index_ms},
                      {"lookup_ms", recurrence.query_ms},
                      {"total_ms", recurrence.total_ms}}},
                    {"stages", stages}};
    objscan::writeFileAtomically(json_path, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("discovery_bench", run, argc, argv);
}
