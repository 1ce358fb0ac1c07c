// Recurrence as the collection grows: a scene's look-ups against catalogs of 10,000, 100,000 and
// 1,000,000 segments, with the peer every look-up would otherwise be, the paper's definition read
// literally (each query scans every segment: the window test, then the 10 nearest in the
// z-normalised measures).
//
//   recurrence_bench [--sizes 10000,100000,1000000] [--queries 200] [--keep DIR]
//
// Each catalog is an SQLite file made by objscan's own Catalog (scenes of 100 segments; extents
// log-uniform from 2 cm to 1 m, measures on their own scales, seeded), in a temporary folder
// (--keep: in DIR, made once and reused). For each size it times what `objscan discover` does
// for one scene of --queries candidates against it: read every segment's extents and measures
// (Catalog::recurrenceEntries), build the index (RecurrenceIndex: kd-tree over log-extents), and
// look the candidates up (recurrences, 10 nearest each, on every core); then one look-up alone
// (nearest, as the collection page asks), and the peer's scan for the same candidates, on one
// core and on every core. The answers are checked against the peer's (largest difference
// printed). Figures are medians of 3 runs.

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <random>

#include <unistd.h>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "bench_main.h"
#include "bench_memory.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/recurrence.h"

namespace {

namespace fs = std::filesystem;
using objscan::discovery::Catalog;
using objscan::discovery::CatalogScene;
using objscan::discovery::CatalogSegment;
using objscan::discovery::RecurrenceEntry;
using objscan::discovery::RecurrenceIndex;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  return x[x.size() / 2];
}

/// A segment as a table top's catalog might hold it.
CatalogSegment randomSegment(std::mt19937* rng) {
  std::uniform_real_distribution<float> log_size(std::log(0.02f), std::log(1.0f));
  std::normal_distribution<double> z(0.0, 1.0);
  CatalogSegment s;
  Eigen::Vector3f e(std::exp(log_size(*rng)), std::exp(log_size(*rng)), std::exp(log_size(*rng)));
  std::sort(e.data(), e.data() + 3, std::greater<float>());
  s.extents = e;
  s.measures.compactness = 0.3 + 0.1 * z(*rng);
  s.measures.symmetry = 0.05 * z(*rng);
  s.measures.smoothness = 0.8 + 0.05 * z(*rng);
  s.measures.local_convexity = 0.6 + 0.2 * z(*rng);
  s.measures.global_convexity = 0.004 * std::abs(z(*rng));
  return s;
}

/// The catalog of `n` segments at `file`, made when it is not there.
void makeCatalog(const fs::path& file, std::size_t n) {
  if (fs::exists(file)) return;
  const fs::path partial = file.string() + ".partial";
  fs::remove(partial);
  std::mt19937 rng(static_cast<unsigned>(n));
  {
    Catalog catalog(partial);
    constexpr std::size_t kPerScene = 100;
    for (std::size_t scene = 0; scene * kPerScene < n; ++scene) {
      CatalogScene s;
      s.name = "scene " + std::to_string(scene);
      s.content_hash = std::to_string(scene);
      s.settings = "bench";
      std::vector<CatalogSegment> segments;
      for (std::size_t i = 0; i < kPerScene && scene * kPerScene + i < n; ++i) {
        segments.push_back(randomSegment(&rng));
      }
      catalog.addScene(s, segments);
    }
  }
  fs::rename(partial, file);
}

/// The paper's definition read literally: for each query, every entry of another scene inside
/// the window, the mean distance to the k nearest in z-normalised measures.
std::vector<double> bruteForce(const std::vector<RecurrenceEntry>& entries,
                               const std::vector<RecurrenceEntry>& queries, bool parallel) {
  std::array<double, 5> mean{}, inv_sd{};
  for (std::size_t j = 0; j < 5; ++j) {
    double sum = 0.0, squares = 0.0;
    for (const RecurrenceEntry& e : entries) sum += e.measures[j];
    mean[j] = sum / static_cast<double>(entries.size());
    for (const RecurrenceEntry& e : entries) squares += std::pow(e.measures[j] - mean[j], 2);
    const double sd = std::sqrt(squares / static_cast<double>(entries.size()));
    inv_sd[j] = sd > 0.0 ? 1.0 / sd : 0.0;
  }
  std::vector<double> out(queries.size());
  const auto one = [&](std::size_t qi) {
    const RecurrenceEntry& q = queries[qi];
    std::vector<double> d;
    for (const RecurrenceEntry& e : entries) {
      if (e.scene_id == q.scene_id) continue;
      bool in = true;
      for (int k = 0; k < 3 && in; ++k) {
        in = std::abs(static_cast<double>(e.extents[k]) - q.extents[k]) <= 0.25 * q.extents[k];
      }
      if (!in) continue;
      double d2 = 0.0;
      for (std::size_t j = 0; j < 5; ++j) {
        d2 += std::pow((e.measures[j] - q.measures[j]) * inv_sd[j], 2);
      }
      d.push_back(std::sqrt(d2));
    }
    if (d.empty()) {
      out[qi] = NAN;
      return;
    }
    const std::size_t k = std::min<std::size_t>(10, d.size());
    std::partial_sort(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
    double sum = 0.0;
    for (std::size_t i = 0; i < k; ++i) sum += d[i];
    out[qi] = sum / static_cast<double>(k);
  };
  if (parallel) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.size()),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i) one(i);
                      });
  } else {
    for (std::size_t i = 0; i < queries.size(); ++i) one(i);
  }
  return out;
}

std::vector<std::size_t> parseSizes(const std::string& text) {
  std::vector<std::size_t> sizes;
  std::size_t at = 0;
  while (at < text.size()) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    sizes.push_back(std::stoul(text.substr(at, comma - at)));
    at = comma + 1;
  }
  return sizes;
}

int run(int argc, char** argv) {
  std::vector<std::size_t> sizes = {10000, 100000, 1000000};
  std::size_t query_count = 200;
  fs::path keep;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--sizes" && i + 1 < argc) {
      sizes = parseSizes(argv[++i]);
    } else if (a == "--queries" && i + 1 < argc) {
      query_count = std::stoul(argv[++i]);
    } else if (a == "--keep" && i + 1 < argc) {
      keep = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: recurrence_bench [--sizes 10000,100000,1000000] [--queries 200] "
                   "[--keep DIR]\n");
      return 2;
    }
  }
  const bool temporary = keep.empty();
  if (temporary) {
    keep = fs::temp_directory_path() / ("recurrence_bench_" + std::to_string(::getpid()));
  }
  fs::create_directories(keep);

  std::printf(
      "segments   catalog  read ms  index ms  %zu look-ups ms  scene total ms  one nearest ms  "
      "peer 1 core ms  peer all cores ms  peer/objscan  max |diff|  MB\n",
      query_count);
  for (const std::size_t n : sizes) {
    const fs::path file = keep / ("catalog_" + std::to_string(n) + ".sqlite");
    const auto made = Clock::now();
    makeCatalog(file, n);
    const double make_ms = msSince(made);
    // The scene looked up: candidates of a scene that is not in the catalog.
    std::mt19937 rng(7);
    std::vector<RecurrenceEntry> queries;
    for (std::size_t i = 0; i < query_count; ++i) {
      const CatalogSegment s = randomSegment(&rng);
      RecurrenceEntry q;
      q.scene_id = -1;
      q.extents = s.extents;
      q.measures = objscan::discovery::recurrenceMeasures(s.measures);
      queries.push_back(q);
    }
    std::vector<double> read_ms, index_ms, lookup_ms, nearest_ms, peer1_ms, peer_ms;
    std::vector<double> got, expected;
    std::vector<RecurrenceEntry> entries;
    const double before = objscan::bench::statusBytes("VmRSS");
    double used = 0.0;  // resident memory above the start, with the entries and the index held
    for (int repeat = 0; repeat < 3; ++repeat) {
      auto t = Clock::now();
      entries = Catalog(file).recurrenceEntries();
      read_ms.push_back(msSince(t));
      t = Clock::now();
      const RecurrenceIndex index(entries);
      index_ms.push_back(msSince(t));
      t = Clock::now();
      got = index.recurrences(queries, -1);
      lookup_ms.push_back(msSince(t));
      t = Clock::now();
      const auto nearest = index.nearest(queries[0].extents, queries[0].measures, -1);
      nearest_ms.push_back(msSince(t));
      used = std::max(used, objscan::bench::statusBytes("VmRSS") - before);
      (void)nearest;
    }
    for (int repeat = 0; repeat < (n >= 1000000 ? 1 : 3); ++repeat) {
      auto t = Clock::now();
      expected = bruteForce(entries, queries, false);
      peer1_ms.push_back(msSince(t));
      t = Clock::now();
      expected = bruteForce(entries, queries, true);
      peer_ms.push_back(msSince(t));
    }
    double max_diff = 0.0;
    for (std::size_t i = 0; i < got.size(); ++i) {
      if (std::isnan(got[i]) != std::isnan(expected[i])) {
        max_diff = INFINITY;
      } else if (!std::isnan(got[i])) {
        max_diff = std::max(max_diff, std::abs(got[i] - expected[i]));
      }
    }
    const double scene = median(read_ms) + median(index_ms) + median(lookup_ms);
    std::printf("%9zu  %6.1f s  %7.0f  %8.0f  %15.1f  %14.0f  %14.3f  %14.0f  %17.0f  %12.0f  %10.1e  %4.0f\n",
                n, make_ms / 1000.0, median(read_ms), median(index_ms), median(lookup_ms), scene,
                median(nearest_ms), median(peer1_ms), median(peer_ms),
                median(peer_ms) / median(lookup_ms), max_diff, used / 1e6);
    std::fflush(stdout);
  }
  if (temporary) fs::remove_all(keep);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("recurrence_bench", run, argc, argv);
}
