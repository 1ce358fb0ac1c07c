#include "objscan/discovery/scenes.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <numbers>
#include <set>
#include <system_error>
#include <utility>

#include "objscan/core/clock.h"
#include "objscan/core/error.h"
#include "objscan/core/file_names.h"
#include "objscan/core/log.h"
#include "objscan/core/memory.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/progress.h"
#include "objscan/core/trajectory.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/evaluation.h"
#include "objscan/discovery/recurrence.h"
#include "stopwatch.h"

namespace objscan::discovery {

namespace {

/// `mesh` laid onto `truth` by alignToTruth (its positions only), with a line saying how far it
/// moved, and a warning when the fit did not settle or made things clearly worse. (Point-to-plane
/// steps minimise the distance along the truth's normals, so the RMS to the closest points can
/// rise by a hair on a mesh already in place: only a tenth more counts.)
TriangleMesh alignedTo(const TriangleMesh& truth, const std::filesystem::path& truth_path,
                       const TriangleMesh& mesh) {
  const TruthAlignment a = alignToTruth(mesh, truth);
  TriangleMesh moved;
  moved.positions.reserve(mesh.positions.size());
  for (const Eigen::Vector3f& p : mesh.positions) moved.positions.push_back(a.T_truth_mesh * p);
  char line[240];
  std::snprintf(line, sizeof line,
                ": the mesh laid onto it: moved %.1f mm (RMS), turned %.2f degrees; RMS "
                "distance %.1f -> %.1f mm (%zu of %zu vertices, %d steps)",
                1000.0 * a.moved_m,
                Eigen::AngleAxisf(a.T_truth_mesh.rotation()).angle() * 180.0 / std::numbers::pi,
                1000.0 * a.rms_before_m, 1000.0 * a.rms_after_m, a.pairs, a.samples, a.iterations);
  log::info(truth_path.string() + line);
  if (!a.converged || a.rms_after_m > 1.1f * a.rms_before_m) {
    log::warning(truth_path.string() + line +
                 (a.converged ? ": the fit made the distance worse"
                              : ": the fit did not settle in its steps"));
  }
  return moved;
}

}  // namespace

GroundTruthObjects truthFromMesh(const std::filesystem::path& truth_path, const TriangleMesh& mesh,
                                 bool align) {
  const TriangleMesh truth = readPly(truth_path);
  if (!truth.hasLabels()) throw InputError(truth_path, "no per-vertex object_id or label");
  try {
    const TriangleMesh aligned = align ? alignedTo(truth, truth_path, mesh) : TriangleMesh{};
    const TriangleMesh& labelled = align ? aligned : mesh;
    if (truth.hasIgnore()) {
      LabelTransfer transfer = transferVertexLabels(labelled, truth, kLabelledMeshDistanceM);
      if (2 * transfer.unmatched > mesh.positions.size()) {
        // Most of the mesh is not where the labels are: another world frame, or another scene.
        log::warning(truth_path.string() + ": " + std::to_string(transfer.unmatched) + " of " +
                     std::to_string(mesh.positions.size()) +
                     " vertices have no labelled vertex within 1.5 cm and are not scored; is the "
                     "mesh in the labels' frame?");
      }
      return GroundTruthObjects(std::move(transfer.labels), std::move(transfer.ignore));
    }
    return GroundTruthObjects(transferLabels(labelled, truth));
  } catch (const std::invalid_argument& e) {
    throw InputError(truth_path, e.what());
  }
}

namespace {

namespace fs = std::filesystem;

/// The mesh file an argument names.
/// Scenes from this size on are announced with an estimate of their time: 6.7 us per vertex,
/// measured with `objscan discover` on TUM fr2/desk fused at 2 mm (2.7 M vertices, 18 s, 2 cores).
constexpr std::size_t kAnnouncedVertices = 1'000'000;
constexpr double kSecondsPerVertex = 6.7e-6;

fs::path meshOf(const fs::path& argument) {
  std::error_code ec;
  const fs::file_type type = fs::status(argument, ec).type();
  if (ec && type != fs::file_type::not_found) {
    throw InputError(argument, "cannot access: " + ec.message());
  }
  if (type != fs::file_type::directory) return argument;
  for (const char* name : {"fused/mesh.ply", "mesh.ply"}) {
    if (fs::is_regular_file(argument / name)) return argument / name;
  }
  throw InputError(argument, "a folder given as a scene must hold fused/mesh.ply or mesh.ply");
}

/// Normals where the mesh has none, then the checks discovery needs; a sentence saying what is
/// wrong otherwise.
void prepareSceneMesh(TriangleMesh& mesh) {
  if (mesh.empty()) throw std::invalid_argument("the mesh has no vertices");
  if (mesh.triangles.empty()) {
    throw std::invalid_argument(
        "the mesh has no faces: discovery needs a triangle mesh, not a point cloud (objscan fuse "
        "writes one)");
  }
  if (!mesh.hasNormals()) mesh.computeNormals();
  mesh.validate();
}

/// The view up of the camera path beside a mesh file (trajectory.txt, as objscan fuse and scan
/// write it); nothing when there is none or it does not read (a warning says why).
std::optional<Eigen::Vector3f> viewUpBeside(const fs::path& mesh_path) {
  const fs::path path = mesh_path.parent_path() / "trajectory.txt";
  if (!fs::is_regular_file(path)) return std::nullopt;
  try {
    const std::optional<Eigen::Vector3f> up = viewUp(readTumTrajectory(path));
    if (up) log::debug(mesh_path.string() + ": up from " + path.string());
    return up;
  } catch (const InputError& e) {
    log::warning(std::string(e.what()) + "; the scene's up is taken as unknown");
    return std::nullopt;
  }
}

/// Alignment moves a fused mesh onto a separate labelled mesh; labels a scene carries itself
/// (a mesh's object_id, a PCD's label field) sit on its own points already.
void warnNotAligned(const fs::path& argument) {
  log::warning(argument.string() +
               ": its labels are its own, on its own points: there is nothing to align it to");
}

GroundTruthObjects groundTruth(const fs::path& argument, const TriangleMesh& mesh, bool align) {
  if (fs::is_directory(argument)) {
    const fs::path truth_path = argument / "scene_gt.ply";
    if (!fs::is_regular_file(truth_path)) {
      throw InputError(argument,
                       "a labelled scene folder needs scene_gt.ply (objscan synth writes it)");
    }
    return truthFromMesh(truth_path, mesh, align);
  }
  if (!mesh.hasLabels()) {
    throw InputError(argument,
                     "no labels: give a folder with scene_gt.ply and a fused mesh, or a "
                     "mesh whose vertices carry object_id (or label, with ignore)");
  }
  if (align) warnNotAligned(argument);
  return GroundTruthObjects(mesh.labels, mesh.ignore);
}

CatalogSegment toCatalog(const Segment& s, const ShapeMeasures& m) {
  CatalogSegment c;
  c.scale = s.scale;
  c.centroid = s.centroid;
  c.axes = s.axes;
  c.eigenvalues = s.eigenvalues;
  c.extents = s.extents;
  c.measures = m;
  c.vertices = s.vertices;
  return c;
}

Segment fromCatalog(CatalogSegment&& c) {
  Segment s;
  s.vertices = std::move(c.vertices);
  s.scale = c.scale;
  s.centroid = c.centroid;
  s.axes = c.axes;
  s.eigenvalues = c.eigenvalues;
  s.extents = c.extents;
  return s;
}

/// The catalog's candidates of a scene it knows, checked against the mesh: a damaged catalog
/// must not index outside it.
void takeFromCatalog(Catalog& catalog, const fs::path& catalog_path, std::int64_t id,
                     DiscoveredScene& scene) {
  scene.from_catalog = true;
  scene.scene_id = id;
  for (CatalogSegment& c : catalog.segments(id, true)) {
    bool valid = !c.vertices.empty();
    for (std::size_t i = 0; valid && i < c.vertices.size(); ++i) {
      valid = c.vertices[i] >= 0 &&
              static_cast<std::size_t>(c.vertices[i]) < scene.mesh.positions.size() &&
              (i == 0 || c.vertices[i - 1] < c.vertices[i]);
    }
    if (!valid) {
      throw InputError(catalog_path, "segment " + std::to_string(c.id) + " of scene " +
                                         std::to_string(id) + " has a damaged vertex list");
    }
    scene.candidates.measures.push_back(c.measures);
    scene.candidates.segments.push_back(fromCatalog(std::move(c)));
  }
  log::debug(scene.name + ": candidates from the catalog");
}

/// The settings for one scene: `config` with the scene's view up, and for a single view its
/// supports' averaged normals, no trimmed feet, no level tops, no standing holder for stacks,
/// regions cut at stacks, and its own floating penalty and region share weight (a scene is always
/// one or the other, so the settings key still names its candidates; the up is in its catalog key,
/// catalogKey).
DiscoveryConfig configOf(const DiscoveredScene& scene, const DiscoveryConfig& config) {
  DiscoveryConfig out = config;
  if (scene.view_up) out.objects.context.view_up = scene.view_up;
  if (scene.single_view) {
    out.supports.trim_feet = false;
    out.supports.normal_rings = out.supports.single_view_normal_rings;
    out.supports.level_tops = false;
    out.objects.context.stacks_need_standing_holder = false;
    out.objects.context.split_regions_at_stacks = true;
    out.objects.floating_penalty = out.objects.single_view_floating_penalty;
    out.objects.region_share_weight = out.objects.single_view_region_share_weight;
    out.convexity.crease_deg = 0.0f;
  }
  return out;
}

/// A scene's key in the catalog: its content hash and, where things on level tops are looked
/// for (`config`, the scene's own from configOf), the camera's up rounded to 0.001: they stand
/// on the ground it finds, so the same mesh with another up is another catalog scene.
/// Catalog::scenesWithHash finds them all by the hash alone.
std::string catalogKey(const std::string& content_hash, const DiscoveryConfig& config) {
  const std::optional<Eigen::Vector3f>& up = config.objects.context.view_up;
  if (content_hash.empty() || !config.supports.enabled || !config.supports.level_tops || !up ||
      !(up->norm() > 0.0f)) {
    return content_hash;
  }
  const Eigen::Vector3f u = up->normalized();
  const auto rounded = [](float x) {  // + 0.0: never "-0.000"
    return std::round(static_cast<double>(x) * 1000.0) / 1000.0 + 0.0;
  };
  char suffix[64];
  std::snprintf(suffix, sizeof suffix, " up %.3f %.3f %.3f", rounded(u.x()), rounded(u.y()),
                rounded(u.z()));
  return content_hash + suffix;
}

/// The content hash a catalog key starts with (catalogKey).
std::string hashOfKey(const std::string& key) { return key.substr(0, key.find(" up ")); }

/// Candidates and measures of one scene: the catalog's when it knows the mesh with these
/// settings, else found now (and added to the catalog).
void findOrRecall(DiscoveredScene& scene, const std::string& content_hash,
                  const SceneDiscoveryOptions& options, const std::string& settings,
                  Catalog* catalog, std::int64_t index) {
  std::optional<CatalogScene> known;
  if (catalog && !content_hash.empty()) known = catalog->findScene(content_hash, settings);
  if (known && known->vertex_count == scene.mesh.positions.size()) {
    takeFromCatalog(*catalog, *options.catalog, known->id, scene);
    addContext(scene.mesh, scene.candidates, configOf(scene, options.config));
    return;
  }
  if (scene.mesh.positions.size() >= kAnnouncedVertices) {
    // A scene this large takes long enough that silence looks like a hang (findCandidates has
    // no finer progress): say what is happening and about how long it takes.
    char line[160];
    std::snprintf(line, sizeof line,
                  ": %.1f M vertices: segmenting and measuring (about %.0f s on 2 cores)",
                  1e-6 * static_cast<double>(scene.mesh.positions.size()),
                  kSecondsPerVertex * static_cast<double>(scene.mesh.positions.size()));
    log::info(scene.name + line);
  }
  scene.candidates = findCandidates(scene.mesh, configOf(scene, options.config));
  // Without a catalog entry, an id no catalog scene has (catalog ids start at 1).
  scene.scene_id = catalog ? -1 - index : index;
  if (catalog && !content_hash.empty()) {
    CatalogScene entry;
    entry.name = scene.name;
    entry.content_hash = content_hash;
    entry.vertex_count = scene.mesh.positions.size();
    entry.settings = settings;
    std::vector<CatalogSegment> rows;
    for (std::size_t i = 0; i < scene.candidates.segments.size(); ++i) {
      rows.push_back(toCatalog(scene.candidates.segments[i], scene.candidates.measures[i]));
    }
    scene.scene_id = catalog->addScene(entry, rows);
  }
}

/// One scene whose candidates get their recurrence: its id among the recurrence entries (the
/// catalog's, or its index in a run without one) and its candidates.
struct RecurrenceScene {
  std::int64_t scene_id = 0;
  SceneCandidates* candidates = nullptr;
};

/// What addRecurrenceAndNormalise found.
struct Normalisation {
  MeasureNormaliser normaliser;
  /// The catalog's scenes and segments measured with these settings; 0 without a catalog.
  std::size_t catalog_scenes = 0, catalog_segments = 0;
};

/// Recurrence of each scene's candidates against every other scene known (the whole catalog's
/// with these settings, or these scenes), then the normaliser: the five measures' over the
/// catalog's segments (with a catalog) or these candidates, recurrence's over these candidates.
/// The one path of discoverScenes and catalogTrainingSet.
Normalisation addRecurrenceAndNormalise(const std::vector<RecurrenceScene>& scenes,
                                        Catalog* catalog, const std::string& settings,
                                        const DiscoveryConfig& config) {
  Normalisation out;
  std::vector<RecurrenceEntry> entries;
  if (catalog) {
    // Only scenes measured with these settings: another run of the same mesh with other
    // settings would otherwise be its own nearest "other scene". Nor the same mesh seen with
    // another camera's up (catalogKey), for the same reason.
    std::set<std::int64_t> own;
    for (const RecurrenceScene& s : scenes) own.insert(s.scene_id);
    const std::vector<CatalogScene> known = catalog->scenes();
    std::set<std::string> own_hashes;
    for (const CatalogScene& c : known) {
      if (own.count(c.id) && !c.content_hash.empty()) own_hashes.insert(hashOfKey(c.content_hash));
    }
    std::set<std::int64_t> comparable;
    for (const CatalogScene& c : known) {
      if (c.settings != settings) continue;
      if (!own.count(c.id) && own_hashes.count(hashOfKey(c.content_hash))) continue;
      comparable.insert(c.id);
    }
    out.catalog_scenes = comparable.size();
    for (RecurrenceEntry& e : catalog->recurrenceEntries()) {
      if (comparable.count(e.scene_id)) entries.push_back(std::move(e));
    }
  } else {
    for (const RecurrenceScene& s : scenes) {
      for (std::size_t i = 0; i < s.candidates->segments.size(); ++i) {
        entries.push_back({s.scene_id, s.candidates->segments[i].extents,
                           recurrenceMeasures(s.candidates->measures[i])});
      }
    }
  }
  std::vector<ShapeMeasures> pool;
  if (catalog) {
    out.catalog_segments = entries.size();
    for (const RecurrenceEntry& e : entries) {
      ShapeMeasures m;
      m.compactness = e.measures[0];
      m.symmetry = e.measures[1];
      m.smoothness = e.measures[2];
      m.local_convexity = e.measures[3];
      m.global_convexity = e.measures[4];
      pool.push_back(m);
    }
  }
  const RecurrenceIndex index(std::move(entries));
  std::vector<ShapeMeasures> measured;
  for (const RecurrenceScene& s : scenes) {
    addRecurrence(*s.candidates, index, s.scene_id, config);
    measured.insert(measured.end(), s.candidates->measures.begin(), s.candidates->measures.end());
  }
  const MeasureNormaliser own = MeasureNormaliser::fit(measured);
  out.normaliser = catalog ? MeasureNormaliser::fit(pool) : own;
  out.normaliser.mean[5] = own.mean[5];
  out.normaliser.sd[5] = own.sd[5];
  return out;
}

/// Scores and suppression within each scene (timed as its suppress stage), then every scene's
/// hypotheses best first.
void rankAll(SceneDiscovery& run, const ObjectnessModel& scorer, const DiscoveryConfig& config) {
  for (std::size_t s = 0; s < run.scenes.size(); ++s) {
    DiscoveredScene& scene = run.scenes[s];
    Stopwatch watch;
    for (Hypothesis& h :
         rankObjects(scene.mesh, scene.candidates, scorer, configOf(scene, config))) {
      run.ranked.push_back({s, std::move(h)});
      ++scene.hypotheses;
    }
    watch.stop(&scene.candidates.timings.suppress_ms, &scene.candidates.timings.suppress_cpu_ms);
  }
  // Every scene's objects before any alternative; objects by object score, the alternatives by
  // score. Within a scene that is rankObjects' order.
  const auto key = [](const Hypothesis& h) {
    const bool object = h.object_rank > 0;
    return std::pair(object ? 0 : 1, object ? -h.object_score : -h.score);
  };
  std::stable_sort(run.ranked.begin(), run.ranked.end(),
                   [&](const RankedHypothesis& a, const RankedHypothesis& b) {
                     return key(a.hypothesis) < key(b.hypothesis);
                   });
}

bool isPcd(const fs::path& path) { return lowercaseExtension(path) == ".pcd"; }

/// Object ids of a mesh's vertices (object parts, as meshOrganized gives them) with each object's
/// parts merged.
std::vector<std::int32_t> wholeObjectIds(std::vector<std::int32_t> parts) {
  for (std::int32_t& id : parts) id = objectIdOfLabel(static_cast<std::uint32_t>(id), true);
  return parts;
}

/// The organized cloud of a PCD file: as stored, or an unorganized one put back on its camera's
/// pixel grid.
OrganizedCloud organizedCloudOf(const fs::path& path, const std::optional<Intrinsics>& camera) {
  OrganizedCloud cloud = readPcd(path);
  if (cloud.organized()) return cloud;
  std::optional<Intrinsics> k = camera ? camera : fitPinhole(cloud);
  if (!k) {
    throw InputError(path,
                     "the cloud is not organized (HEIGHT 1) and its points do not fit a camera's "
                     "pixel grid: give the camera's intrinsics with --intrinsics");
  }
  try {
    return placeOnPixelGrid(cloud, *k);
  } catch (const std::invalid_argument& e) {
    throw InputError(path, std::string("the intrinsics to put it on its pixel grid: ") + e.what());
  }
}

}  // namespace

SceneInput sceneFromCloud(std::string name, const OrganizedCloud& cloud, bool labelled,
                          const OrganizedMeshConfig& meshing) {
  if (labelled && cloud.labels.empty()) {
    throw InputError(name, "no label field: a labelled point cloud needs one per point");
  }
  TriangleMesh mesh;
  try {
    mesh = meshOrganized(cloud, meshing);
  } catch (const std::invalid_argument& e) {
    throw InputError(name, e.what());
  }
  if (mesh.empty())
    throw InputError(name, "the cloud has no valid point (all NaN or behind the camera)");
  if (mesh.triangles.empty()) {
    throw InputError(name, "no two neighbouring pixels of the cloud join into a surface");
  }
  SceneInput scene;
  scene.name = std::move(name);
  scene.view_up = Eigen::Vector3f(0.0f, -1.0f, 0.0f);  // the points are in the camera's frame
  scene.single_view = true;
  if (labelled) {
    try {
      scene.whole_objects.emplace(wholeObjectIds(mesh.labels));
      scene.truth.emplace(mesh.labels);
    } catch (const std::invalid_argument& e) {
      throw InputError(scene.name, e.what());
    }
  }
  // The labels are ground truth, not something discovery reads.
  mesh.labels.clear();
  scene.mesh = std::move(mesh);
  try {
    prepareSceneMesh(scene.mesh);
  } catch (const std::invalid_argument& e) {
    throw InputError(scene.name, e.what());
  }
  return scene;
}

SceneInput loadScene(const fs::path& argument, const SceneReading& reading) {
  if (isPcd(argument)) {
    if (reading.labelled && reading.align_truth) warnNotAligned(argument);
    SceneInput scene =
        sceneFromCloud(argument.string(), organizedCloudOf(argument, reading.intrinsics),
                       reading.labelled, reading.meshing);
    if (reading.hash) scene.content_hash = contentHash(argument);
    if (reading.view_up) scene.view_up = reading.view_up;
    return scene;
  }
  SceneInput scene;
  const fs::path mesh_path = meshOf(argument);
  scene.name = mesh_path.string();
  scene.mesh = readPly(mesh_path);
  try {
    prepareSceneMesh(scene.mesh);
  } catch (const std::invalid_argument& e) {
    throw InputError(mesh_path, e.what());
  }
  if (reading.hash) scene.content_hash = contentHash(mesh_path);
  scene.view_up = reading.view_up ? reading.view_up : viewUpBeside(mesh_path);
  if (reading.labelled) {
    try {
      scene.truth.emplace(groundTruth(argument, scene.mesh, reading.align_truth));
    } catch (const std::invalid_argument& e) {
      throw InputError(argument, e.what());
    }
  }
  return scene;
}

SceneInput sceneFromMesh(std::string name, TriangleMesh mesh, std::string content_hash) {
  SceneInput scene;
  scene.name = std::move(name);
  scene.mesh = std::move(mesh);
  prepareSceneMesh(scene.mesh);
  scene.content_hash = std::move(content_hash);
  return scene;
}

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

void requireMemoryFor(const std::vector<SceneInput>& inputs) {
  std::uint64_t largest = 0, total = 0;
  for (const SceneInput& input : inputs) {
    largest = std::max<std::uint64_t>(largest, input.mesh.positions.size());
    total += input.mesh.positions.size();
  }
  const std::uint64_t needed = 1000 * largest + 150 * total;
  const std::optional<std::uint64_t> available = availableMemoryBytes();
  if (!available || needed <= *available) return;
  throw std::runtime_error(
      "discovery of " + std::to_string(inputs.size()) +
      (inputs.size() == 1 ? " scene" : " scenes") + " (the largest " + std::to_string(largest) +
      " vertices) needs about " + bytesText(needed) + ", more than " +
      availableMemoryText(*available) +
      ": fuse with a larger --voxel-size (twice the size, about a quarter of the vertices) or "
      "give fewer scenes at once");
}

SceneDiscovery discoverScenes(std::vector<SceneInput> inputs,
                              const SceneDiscoveryOptions& options) {
  const auto start = SteadyClock::now();
  options.config.validate();
  requireMemoryFor(inputs);
  std::optional<Catalog> catalog;
  if (options.catalog) catalog.emplace(*options.catalog);
  const std::string settings = settingsKey(options.config);

  SceneDiscovery run;
  run.catalog = options.catalog;
  run.scenes.reserve(inputs.size());
  ProgressBar progress(options.progress_label, inputs.size());
  for (SceneInput& input : inputs) {
    DiscoveredScene scene;
    scene.name = std::move(input.name);
    scene.mesh = std::move(input.mesh);
    scene.truth = std::move(input.truth);
    scene.whole_objects = std::move(input.whole_objects);
    scene.view_up = input.view_up;
    scene.single_view = input.single_view;
    scene.content_hash = catalogKey(input.content_hash, configOf(scene, options.config));
    findOrRecall(scene, scene.content_hash, options, settings, catalog ? &*catalog : nullptr,
                 static_cast<std::int64_t>(run.scenes.size()));
    run.scenes.push_back(std::move(scene));
    progress.advance();
  }
  progress.finish();
  std::vector<RecurrenceScene> measured;
  for (DiscoveredScene& scene : run.scenes) measured.push_back({scene.scene_id, &scene.candidates});
  const Normalisation normalised =
      addRecurrenceAndNormalise(measured, catalog ? &*catalog : nullptr, settings, options.config);
  run.normaliser = normalised.normaliser;
  run.catalog_scenes = normalised.catalog_scenes;
  run.catalog_segments = normalised.catalog_segments;

  const ObjectnessModel scorer =
      options.model ? *options.model
                    : ObjectnessModel::average(run.normaliser, varyingMeasures(run.normaliser));
  rankAll(run, scorer, options.config);
  run.scorer = scorer.kind();
  run.normalised_over = options.model     ? "the model's training segments"
                        : options.catalog ? "catalog"
                                          : "these scenes";
  run.seconds = secondsSince(start);
  return run;
}

CatalogTrainingSet catalogTrainingSet(const fs::path& catalog_path, const DiscoveryConfig& config) {
  config.validate();
  std::error_code ec;
  if (!fs::exists(catalog_path, ec)) {
    throw InputError(catalog_path,
                     "no such catalog (objscan discover --catalog makes one; objscan view labels "
                     "its segments)");
  }
  Catalog catalog(catalog_path);
  const std::string settings = settingsKey(config);
  CatalogTrainingSet out;
  // The scenes with labels to use, each with every one of its segments: recurrence is computed
  // and normalised over whole scenes, as discoverScenes does for the scenes it is given.
  struct LabelledScene {
    std::int64_t id = 0;
    SceneCandidates candidates;
    std::vector<std::int64_t> segment_ids;
    std::vector<std::optional<int>> labels;
  };
  std::vector<LabelledScene> scenes;
  for (const CatalogScene& scene : catalog.scenes()) {
    const LabelCounts counts = catalog.labelCounts(scene.id);
    if (scene.settings != settings) {
      out.other_settings += counts.labelled;
      continue;
    }
    out.unsure += counts.unsure;
    if (counts.objects + counts.not_objects == 0) continue;
    LabelledScene& labelled = scenes.emplace_back();
    labelled.id = scene.id;
    for (CatalogSegment& c : catalog.segments(scene.id, false)) {
      labelled.segment_ids.push_back(c.id);
      labelled.labels.push_back(c.label);
      labelled.candidates.measures.push_back(c.measures);
      labelled.candidates.segments.push_back(fromCatalog(std::move(c)));
    }
  }
  out.scenes = scenes.size();
  if (scenes.empty()) return out;
  std::vector<RecurrenceScene> measured;
  for (LabelledScene& s : scenes) measured.push_back({s.id, &s.candidates});
  out.normaliser = addRecurrenceAndNormalise(measured, &catalog, settings, config).normaliser;
  for (std::size_t k = 0; k < scenes.size(); ++k) {
    const LabelledScene& s = scenes[k];
    for (std::size_t i = 0; i < s.labels.size(); ++i) {
      const std::optional<int>& label = s.labels[i];
      if (label != static_cast<int>(SegmentLabel::kObject) &&
          label != static_cast<int>(SegmentLabel::kNotObject)) {
        continue;
      }
      out.measures.push_back(s.candidates.measures[i]);
      out.labels.push_back(*label);
      out.segment_ids.push_back(s.segment_ids[i]);
      out.scene_of.push_back(k);
    }
  }
  return out;
}

std::vector<int> LabelledSegments::labels(double min_iou) const {
  std::vector<int> out;
  out.reserve(matches.size());
  for (const ObjectMatch& m : matches) out.push_back(isObject(m, min_iou));
  return out;
}

LabelledSegments labelledSegments(const SceneDiscovery& run, double max_iou) {
  LabelledSegments out;
  const ObjectnessModel average =
      ObjectnessModel::average(run.normaliser, varyingMeasures(run.normaliser));
  for (std::size_t s = 0; s < run.scenes.size(); ++s) {
    if (!run.scenes[s].truth) {
      throw std::invalid_argument(run.scenes[s].name +
                                  ": a labelled run needs every scene's truth");
    }
    const GroundTruthObjects& truth = *run.scenes[s].truth;
    for (const Hypothesis& h : rankCandidates(run.scenes[s].candidates, average, max_iou)) {
      out.measures.push_back(h.measures);
      out.matches.push_back(truth.bestMatch(h.segment.vertices));
      out.scene.push_back(s);
    }
  }
  return out;
}

std::vector<ObjectRecall> objectRecall(const SceneDiscovery& run, const LabelledSegments& kept) {
  std::vector<ObjectRecall> out;
  for (std::size_t s = 0; s < run.scenes.size(); ++s) {
    const GroundTruthObjects& truth = run.scenes[s].truth.value();
    std::map<std::int32_t, double> best_candidate, best_kept;
    for (std::int32_t id : truth.objectIds()) best_candidate[id] = best_kept[id] = 0.0;
    for (const Segment& seg : run.scenes[s].candidates.segments) {
      const ObjectMatch m = truth.bestMatch(seg.vertices);
      if (m.object_id != 0)
        best_candidate[m.object_id] = std::max(best_candidate[m.object_id], m.iou);
    }
    for (std::size_t i = 0; i < kept.matches.size(); ++i) {
      const ObjectMatch& m = kept.matches[i];
      if (kept.scene[i] == s && m.object_id != 0) {
        best_kept[m.object_id] = std::max(best_kept[m.object_id], m.iou);
      }
    }
    for (const auto& [id, iou] : best_candidate) {
      out.push_back({s, id, truth.objectSize(id), iou, best_kept[id]});
    }
  }
  return out;
}

std::vector<SceneRecall> sceneRecall(const SceneDiscovery& run, bool whole_objects) {
  std::vector<std::vector<std::vector<std::int32_t>>> ranked(run.scenes.size());
  for (const RankedHypothesis& h : run.ranked)
    ranked[h.scene].push_back(h.hypothesis.segment.vertices);
  std::vector<SceneRecall> out;
  for (std::size_t s = 0; s < run.scenes.size(); ++s) {
    const DiscoveredScene& scene = run.scenes[s];
    if (!scene.truth) {
      throw std::invalid_argument(scene.name + ": a labelled run needs every scene's truth");
    }
    const GroundTruthObjects& truth =
        whole_objects && scene.whole_objects ? *scene.whole_objects : *scene.truth;
    const RankingEvaluation at05 = evaluateRanking(truth, ranked[s], 0.5);
    const RankingEvaluation at07 = evaluateRanking(truth, ranked[s], 0.7);
    SceneRecall r;
    r.scene = s;
    r.objects = at05.objects;
    if (r.objects > 0) {
      r.recall_05 = static_cast<double>(at05.found) / static_cast<double>(r.objects);
      r.recall_07 = static_cast<double>(at07.found) / static_cast<double>(r.objects);
    }
    r.ap_05 = at05.ap;
    r.ap_07 = at07.ap;
    out.push_back(r);
  }
  return out;
}

std::vector<Hypothesis> discoverObjects(const TriangleMesh& mesh, const DiscoveryConfig& config,
                                        DiscoveryTimings* timings) {
  SceneDiscoveryOptions options;
  options.config = config;
  options.progress_label.clear();
  std::vector<SceneInput> one;
  one.push_back(sceneFromMesh("mesh", mesh));
  SceneDiscovery run = discoverScenes(std::move(one), options);
  if (timings) *timings = run.scenes.at(0).candidates.timings;
  std::vector<Hypothesis> out;
  out.reserve(run.ranked.size());
  for (RankedHypothesis& r : run.ranked) out.push_back(std::move(r.hypothesis));
  return out;
}

}  // namespace objscan::discovery
