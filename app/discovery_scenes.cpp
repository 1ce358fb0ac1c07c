#include "discovery_scenes.h"

#include <cstdlib>
#include <set>
#include <system_error>

#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/progress.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/recurrence.h"

namespace objscan::app {

std::vector<std::int32_t> labelsFromTruthMesh(const std::filesystem::path& truth_path,
                                              const TriangleMesh& mesh) {
  const TriangleMesh truth = readPly(truth_path);
  if (!truth.hasLabels()) throw InputError(truth_path, "no per-vertex object_id");
  try {
    return discovery::transferLabels(mesh, truth);
  } catch (const std::invalid_argument& e) {
    throw InputError(truth_path, e.what());
  }
}

namespace {

namespace fs = std::filesystem;

/// The mesh file an argument names.
fs::path meshOf(const fs::path& argument) {
  if (!fs::is_directory(argument)) return argument;
  for (const char* name : {"fused/mesh.ply", "mesh.ply"}) {
    if (fs::is_regular_file(argument / name)) return argument / name;
  }
  throw InputError(argument, "a folder given as a scene must hold fused/mesh.ply or mesh.ply");
}

/// Reads a scene mesh that discovery can use, or throws InputError saying why not.
TriangleMesh readSceneMesh(const fs::path& path) {
  TriangleMesh mesh = readPly(path);
  if (mesh.empty()) throw InputError(path, "the mesh has no vertices");
  if (mesh.triangles.empty()) {
    throw InputError(path,
                     "the mesh has no faces: discovery needs a triangle mesh, not a point "
                     "cloud (objscan fuse writes one)");
  }
  if (!mesh.hasNormals()) mesh.computeNormals();
  try {
    mesh.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(path, e.what());
  }
  return mesh;
}

std::vector<std::int32_t> groundTruthLabels(const fs::path& argument, const TriangleMesh& mesh) {
  if (fs::is_directory(argument)) {
    const fs::path truth_path = argument / "scene_gt.ply";
    if (!fs::is_regular_file(truth_path)) {
      throw InputError(argument,
                       "a labelled scene folder needs scene_gt.ply (objscan synth "
                       "writes it)");
    }
    return labelsFromTruthMesh(truth_path, mesh);
  }
  if (!mesh.hasLabels()) {
    throw InputError(argument,
                     "no labels: give a folder with scene_gt.ply and a fused mesh, or a "
                     "mesh whose vertices carry object_id");
  }
  return mesh.labels;
}

discovery::CatalogSegment toCatalog(const discovery::Segment& s,
                                    const discovery::ShapeMeasures& m) {
  discovery::CatalogSegment c;
  c.scale = s.scale;
  c.centroid = s.centroid;
  c.axes = s.axes;
  c.eigenvalues = s.eigenvalues;
  c.extents = s.extents;
  c.measures = m;
  c.vertices = s.vertices;
  return c;
}

discovery::Segment fromCatalog(discovery::CatalogSegment&& c) {
  discovery::Segment s;
  s.vertices = std::move(c.vertices);
  s.scale = c.scale;
  s.centroid = c.centroid;
  s.axes = c.axes;
  s.eigenvalues = c.eigenvalues;
  s.extents = c.extents;
  return s;
}

}  // namespace

fs::path defaultCatalogPath() {
  fs::path dir;
  if (const char* env = std::getenv("OBJSCAN_CATALOG"); env && *env) return env;
  if (const char* xdg = std::getenv("XDG_DATA_HOME"); xdg && *xdg) {
    dir = fs::path(xdg) / "objscan";
  } else if (const char* home = std::getenv("HOME"); home && *home) {
    dir = fs::path(home) / ".local" / "share" / "objscan";
  } else {
    throw std::invalid_argument("no default catalog location (HOME is not set): give --catalog");
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw OutputError(dir, "cannot create the catalog's folder: " + ec.message());
  return dir / "catalog.sqlite";
}

SceneSet readScenes(const std::vector<fs::path>& arguments, const SceneSetOptions& options) {
  options.config.validate();
  std::optional<discovery::Catalog> catalog;
  if (options.catalog) catalog.emplace(*options.catalog);
  const std::string settings = discovery::settingsKey(options.config);

  SceneSet set;
  std::vector<LoadedScene>& scenes = set.scenes;
  scenes.reserve(arguments.size());
  ProgressBar progress("finding candidates", arguments.size());
  for (const fs::path& argument : arguments) {
    LoadedScene scene;
    scene.argument = argument;
    scene.mesh_path = meshOf(argument);
    scene.mesh = readSceneMesh(scene.mesh_path);
    if (options.labelled) {
      try {
        scene.truth.emplace(groundTruthLabels(argument, scene.mesh));
      } catch (const std::invalid_argument& e) {
        throw InputError(argument, e.what());
      }
    }
    std::optional<discovery::CatalogScene> known;
    std::string hash;
    if (catalog) {
      hash = discovery::contentHash(scene.mesh_path);
      known = catalog->findScene(hash, settings);
    }
    if (known && known->vertex_count == scene.mesh.positions.size()) {
      scene.from_catalog = true;
      scene.scene_id = known->id;
      for (discovery::CatalogSegment& c : catalog->segments(known->id, true)) {
        // A damaged catalog must not index outside the mesh.
        bool valid = !c.vertices.empty();
        for (std::size_t i = 0; valid && i < c.vertices.size(); ++i) {
          valid = c.vertices[i] >= 0 &&
                  static_cast<std::size_t>(c.vertices[i]) < scene.mesh.positions.size() &&
                  (i == 0 || c.vertices[i - 1] < c.vertices[i]);
        }
        if (!valid) {
          throw InputError(*options.catalog, "segment " + std::to_string(c.id) + " of scene " +
                                                 std::to_string(known->id) +
                                                 " has a damaged vertex list");
        }
        scene.candidates.measures.push_back(c.measures);
        scene.candidates.segments.push_back(fromCatalog(std::move(c)));
      }
      log::debug(scene.mesh_path.string() + ": candidates from the catalog");
    } else {
      scene.candidates = discovery::findCandidates(scene.mesh, options.config);
      if (catalog) {
        discovery::CatalogScene entry;
        entry.name = scene.mesh_path.string();
        entry.content_hash = hash;
        entry.vertex_count = scene.mesh.positions.size();
        entry.settings = settings;
        std::vector<discovery::CatalogSegment> rows;
        for (std::size_t i = 0; i < scene.candidates.segments.size(); ++i) {
          rows.push_back(toCatalog(scene.candidates.segments[i], scene.candidates.measures[i]));
        }
        scene.scene_id = catalog->addScene(entry, rows);
      } else {
        scene.scene_id = static_cast<std::int64_t>(scenes.size());
      }
    }
    scenes.push_back(std::move(scene));
    progress.advance();
  }
  progress.finish();

  // Recurrence against every other scene known: the whole catalog, or this run's scenes.
  std::vector<discovery::RecurrenceEntry> entries;
  if (catalog) {
    // Only scenes measured with these settings: another run of the same mesh with other
    // settings would otherwise be its own nearest "other scene".
    std::set<std::int64_t> comparable;
    for (const discovery::CatalogScene& c : catalog->scenes()) {
      if (c.settings == settings) comparable.insert(c.id);
    }
    set.catalog_scenes = comparable.size();
    for (discovery::RecurrenceEntry& e : catalog->recurrenceEntries()) {
      if (comparable.count(e.scene_id)) entries.push_back(std::move(e));
    }
  } else {
    for (const LoadedScene& s : scenes) {
      for (std::size_t i = 0; i < s.candidates.segments.size(); ++i) {
        entries.push_back({s.scene_id, s.candidates.segments[i].extents,
                           discovery::recurrenceMeasures(s.candidates.measures[i])});
      }
    }
  }
  std::vector<discovery::ShapeMeasures> pool;
  if (catalog) {
    set.catalog_segments = entries.size();
    for (const discovery::RecurrenceEntry& e : entries) {
      discovery::ShapeMeasures m;
      m.compactness = e.measures[0];
      m.symmetry = e.measures[1];
      m.smoothness = e.measures[2];
      m.local_convexity = e.measures[3];
      m.global_convexity = e.measures[4];
      pool.push_back(m);
    }
  }
  const discovery::RecurrenceIndex index(std::move(entries));
  std::vector<discovery::ShapeMeasures> run;
  for (LoadedScene& s : scenes) {
    discovery::addRecurrence(s.candidates, index, s.scene_id, options.config);
    run.insert(run.end(), s.candidates.measures.begin(), s.candidates.measures.end());
  }
  const discovery::MeasureNormaliser own = discovery::MeasureNormaliser::fit(run);
  set.normaliser = catalog ? discovery::MeasureNormaliser::fit(pool) : own;
  set.normaliser.mean[5] = own.mean[5];
  set.normaliser.sd[5] = own.sd[5];
  return set;
}

std::vector<int> LabelledSegments::labels(double min_iou) const {
  std::vector<int> out;
  out.reserve(matches.size());
  for (const discovery::ObjectMatch& m : matches) out.push_back(discovery::isObject(m, min_iou));
  return out;
}

LabelledSegments labelledSegments(const SceneSet& set, double max_iou) {
  LabelledSegments out;
  const discovery::ObjectnessModel average = discovery::ObjectnessModel::average(
      set.normaliser, discovery::varyingMeasures(set.normaliser));
  for (std::size_t s = 0; s < set.scenes.size(); ++s) {
    const discovery::GroundTruthObjects& truth = *set.scenes[s].truth;
    for (const discovery::Hypothesis& h :
         discovery::rankCandidates(set.scenes[s].candidates, average, max_iou)) {
      out.measures.push_back(h.measures);
      out.matches.push_back(truth.bestMatch(h.segment.vertices));
      out.scene.push_back(s);
    }
  }
  return out;
}

}  // namespace objscan::app
