#include "objscan/pipeline/collection.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "objscan/core/atomic_file.h"
#include "objscan/core/clock.h"
#include "objscan/core/error.h"
#include "objscan/core/image_codec.h"
#include "objscan/core/log.h"
#include "objscan/core/progress.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/recurrence.h"
#include "objscan/discovery/segment.h"
#include "objscan/render/snapshots.h"
#include "objscan/report/collection_page.h"
#include "objscan/report/results_io.h"

namespace objscan::pipeline {
namespace {

namespace fs = std::filesystem;
using report::CollectionItem;

constexpr const char* kPictureFolder = "collection/pictures";

/// The recording a scene of the collection belongs to: the folder its mesh is in
/// (DIR/<name>/mesh.ply).
std::string recordingOf(const report::SceneRecord& s) {
  const fs::path mesh = s.mesh_absolute.empty() ? fs::path(s.mesh) : fs::path(s.mesh_absolute);
  return mesh.parent_path().filename().string();
}

/// A path as one shell word: as it is when it holds only safe characters, else in single quotes.
std::string shellQuoted(const std::string& text) {
  if (!text.empty() && text.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                              "0123456789/._-+=:,") == std::string::npos) {
    return text;
  }
  std::string out = "'";
  for (const char c : text) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

Eigen::Vector3f decreasing(Eigen::Vector3f e) {
  std::sort(e.data(), e.data() + 3, std::greater<float>());
  return e;
}

/// Whether two segments of one scene share more than half of the smaller one's vertices (the
/// same object at two scales). Vertex lists are increasing.
bool mostlyShared(const discovery::CatalogSegment& a, const discovery::CatalogSegment& b) {
  return 2 * discovery::sharedVertexCount(a.vertices, b.vertices) >
         std::min(a.vertices.size(), b.vertices.size());
}

/// A picture to render: a segment of a scene, ranked (painted in its rank's colour with the
/// rank in its corner, together with the scene's other objects, which never overlap) or not (on
/// its own).
struct PictureJob {
  std::string file;  ///< relative to the batch folder
  std::vector<std::int32_t> vertices;
  std::size_t rank = 0;  ///< an object of the collection's object set; 0 for any other segment
  double score = 0.0;
  std::vector<CollectionItem*> items;  ///< the items that show it
};

/// What the page is made of, with the vertices its pictures need.
class PageBuilder {
 public:
  PageBuilder(const fs::path& dir, const std::vector<CollectionRecording>& recordings,
              const CollectionPageOptions& options)
      : dir_(dir), options_(options) {
    hypotheses_ = report::readHypotheses(dir / "collection" / report::kHypothesesFile);
    page_.title = dir.string();
    page_.viewer_url = options.viewer_url;
    // At the address the links name: a viewer already there makes this one fail, not move.
    page_.view_command = "objscan view " + shellQuoted((dir / "collection").string()) +
                         " --serve 127.0.0.1:8090";
    std::map<std::string, std::string> sources;
    for (const CollectionRecording& r : recordings) sources.emplace(r.name, r.source);
    for (std::size_t i = 0; i < hypotheses_.scenes.size(); ++i) {
      const report::SceneRecord& s = hypotheses_.scenes[i];
      report::CollectionSceneEntry entry;
      entry.name = recordingOf(s);
      const auto source = sources.find(entry.name);
      entry.source = source != sources.end() ? source->second : s.mesh;
      if (fs::is_regular_file(dir / entry.name / report::kReportFile)) {
        entry.report = entry.name + "/" + report::kReportFile;
      }
      scene_of_mesh_.emplace(s.mesh, i);
      if (s.catalog_scene) scene_of_catalog_.emplace(*s.catalog_scene, i);
      page_.scenes.push_back(std::move(entry));
    }
    page_.failed = recordings.size() > page_.scenes.size()
                       ? recordings.size() - page_.scenes.size()
                       : 0;
    for (const report::HypothesisRecord& h : hypotheses_.hypotheses) {
      const auto scene = scene_of_mesh_.find(h.scene);
      if (scene == scene_of_mesh_.end()) continue;
      report::CollectionSceneEntry& entry = page_.scenes[scene->second];
      ++entry.hypotheses;
      if (h.object_rank.value_or(0) > 0 && entry.objects.size() < options.objects_per_scene) {
        entry.objects.push_back(hypothesisItem(h, scene->second));
      }
    }
  }

  /// Objects across scenes: the collection's best objects and their nearest segments of other
  /// scenes in the catalog.
  void addGroups() {
    const fs::path catalog_path =
        hypotheses_.catalog ? fs::path(hypotheses_.catalog->path) : fs::path();
    if (catalog_path.empty() || !fs::is_regular_file(catalog_path)) {
      page_.groups_missing =
          "No catalog (the batch ran with --no-catalog): objects across scenes are the catalog's "
          "segments compared across scenes.";
      return;
    }
    if (page_.scenes.size() < 2) {
      page_.groups_missing = "One scene: there is no other scene to compare its objects with.";
      return;
    }
    catalog_ = std::make_unique<discovery::Catalog>(catalog_path);
    std::vector<discovery::RecurrenceEntry> entries = catalog_->recurrenceEntries();
    std::vector<std::pair<std::int64_t, std::int64_t>> ids;  // (scene, segment) by entry
    ids.reserve(entries.size());
    for (const discovery::RecurrenceEntry& e : entries) ids.emplace_back(e.scene_id, e.segment_id);
    const discovery::RecurrenceIndex index(std::move(entries));
    for (const report::HypothesisRecord& h : hypotheses_.hypotheses) {
      if (page_.groups.size() >= options_.groups) break;
      if (h.object_rank.value_or(0) == 0) continue;
      const auto scene = scene_of_mesh_.find(h.scene);
      if (scene == scene_of_mesh_.end()) continue;
      const std::optional<std::int64_t> catalog_scene =
          hypotheses_.scenes[scene->second].catalog_scene;
      if (!catalog_scene) continue;
      const discovery::CatalogSegment* segment = segmentWithVertices(*catalog_scene, h.vertices);
      if (!segment) continue;
      report::CollectionGroup group;
      group.query = hypothesisItem(h, scene->second);
      group.query.segment = segment->id;
      group.query.extents = decreasing(segment->extents);
      // One segment per object: the catalog holds an object at several scales, and the same
      // object twice says nothing; three times the neighbours are asked for to fill the row.
      std::vector<std::pair<std::int64_t, const discovery::CatalogSegment*>> shown;
      for (const discovery::RecurrenceNeighbour& n :
           index.nearest(segment->extents, discovery::recurrenceMeasures(segment->measures),
                         *catalog_scene, 3 * options_.neighbours)) {
        if (group.neighbours.size() >= static_cast<std::size_t>(options_.neighbours)) break;
        const auto [scene_id, segment_id] = ids[n.entry];
        const auto neighbour_scene = scene_of_catalog_.find(scene_id);
        if (neighbour_scene == scene_of_catalog_.end()) continue;  // not among the scenes shown
        const discovery::CatalogSegment* found = segmentWithId(scene_id, segment_id);
        if (!found) continue;
        const std::int64_t in_scene = scene_id;  // (clang 14 captures no structured binding)
        const bool again = std::any_of(shown.begin(), shown.end(), [&](const auto& other) {
          return other.first == in_scene && mostlyShared(*other.second, *found);
        });
        if (again) continue;
        shown.emplace_back(scene_id, found);
        group.neighbours.push_back(segmentItem(*found, neighbour_scene->second, n.distance));
      }
      page_.groups.push_back(std::move(group));
    }
    if (page_.groups.empty()) {
      page_.groups_missing = "No object of the collection is in the catalog to compare.";
    }
  }

  /// The pictures each item needs, one job per distinct picture, by scene.
  std::map<std::size_t, std::vector<PictureJob>> pictureJobs() {
    std::map<std::size_t, std::vector<PictureJob>> by_scene;
    std::map<std::string, std::pair<std::size_t, std::size_t>> where;  // file -> job
    const auto add = [&](CollectionItem& item) {
      const bool ranked = item.rank && isObject(*item.rank);
      const std::string file =
          std::string(kPictureFolder) + "/" +
          (ranked ? "scene_" + std::to_string(item.scene_index) + "_rank_" +
                        std::to_string(*item.rank) + ".png"
                  : "segment_" + std::to_string(item.segment.value_or(0)) + ".png");
      if (const auto it = where.find(file); it != where.end()) {
        by_scene[it->second.first][it->second.second].items.push_back(&item);
        return;
      }
      PictureJob job;
      job.file = file;
      job.vertices = verticesOf(item);
      if (job.vertices.empty()) return;
      job.rank = ranked ? *item.rank : 0;
      job.score = item.score.value_or(NAN);
      job.items.push_back(&item);
      std::vector<PictureJob>& jobs = by_scene[item.scene_index];
      where.emplace(file, std::make_pair(item.scene_index, jobs.size()));
      jobs.push_back(std::move(job));
    };
    for (report::CollectionSceneEntry& s : page_.scenes) {
      for (CollectionItem& item : s.objects) add(item);
    }
    for (report::CollectionGroup& g : page_.groups) {
      add(g.query);
      for (CollectionItem& item : g.neighbours) add(item);
    }
    return by_scene;
  }

  report::CollectionPage& page() { return page_; }
  const report::SceneRecord& scene(std::size_t i) const { return hypotheses_.scenes[i]; }

 private:
  CollectionItem hypothesisItem(const report::HypothesisRecord& h, std::size_t scene) {
    CollectionItem item;
    item.scene = page_.scenes[scene].name;
    item.scene_index = scene;
    item.rank = h.rank;
    item.score = h.objectScoreIfObject() ? h.objectScoreIfObject() : h.score;
    if (h.box) item.extents = decreasing(h.box->extents);
    hypothesis_vertices_[h.rank] = &h.vertices;
    if (h.object_rank.value_or(0) > 0) objects_.insert(h.rank);
    return item;
  }

  CollectionItem segmentItem(const discovery::CatalogSegment& s, std::size_t scene,
                             double distance) {
    CollectionItem item;
    item.scene = page_.scenes[scene].name;
    item.scene_index = scene;
    item.segment = s.id;
    item.distance = distance;
    item.extents = decreasing(s.extents);
    // A segment that is one of the collection's hypotheses links to it by its rank.
    for (const report::HypothesisRecord& h : hypotheses_.hypotheses) {
      if (h.scene == hypotheses_.scenes[scene].mesh && h.vertices == s.vertices) {
        item.rank = h.rank;
        item.score = h.objectScoreIfObject() ? h.objectScoreIfObject() : h.score;
        hypothesis_vertices_[h.rank] = &h.vertices;
        if (h.object_rank.value_or(0) > 0) objects_.insert(h.rank);
        break;
      }
    }
    segment_vertices_[s.id] = &s.vertices;
    return item;
  }

  bool isObject(std::size_t rank) const { return objects_.count(rank) > 0; }

  std::vector<std::int32_t> verticesOf(const CollectionItem& item) const {
    if (item.rank) {
      if (const auto it = hypothesis_vertices_.find(*item.rank); it != hypothesis_vertices_.end()) {
        return *it->second;
      }
    }
    if (item.segment) {
      if (const auto it = segment_vertices_.find(*item.segment); it != segment_vertices_.end()) {
        return *it->second;
      }
    }
    return {};
  }

  const std::vector<discovery::CatalogSegment>& segmentsOf(std::int64_t scene_id) {
    auto it = segments_.find(scene_id);
    if (it == segments_.end()) {
      it = segments_.emplace(scene_id, catalog_->segments(scene_id, true)).first;
    }
    return it->second;
  }

  const discovery::CatalogSegment* segmentWithVertices(std::int64_t scene_id,
                                                       const std::vector<std::int32_t>& vertices) {
    for (const discovery::CatalogSegment& s : segmentsOf(scene_id)) {
      if (s.vertices == vertices) return &s;
    }
    return nullptr;
  }

  const discovery::CatalogSegment* segmentWithId(std::int64_t scene_id, std::int64_t id) {
    for (const discovery::CatalogSegment& s : segmentsOf(scene_id)) {
      if (s.id == id) return &s;
    }
    return nullptr;
  }

  fs::path dir_;
  const CollectionPageOptions& options_;
  report::Hypotheses hypotheses_;
  report::CollectionPage page_;
  std::map<std::string, std::size_t> scene_of_mesh_;
  std::map<std::int64_t, std::size_t> scene_of_catalog_;
  std::unique_ptr<discovery::Catalog> catalog_;
  std::map<std::int64_t, std::vector<discovery::CatalogSegment>> segments_;  // by catalog scene
  std::map<std::size_t, const std::vector<std::int32_t>*> hypothesis_vertices_;  // by rank
  std::map<std::int64_t, const std::vector<std::int32_t>*> segment_vertices_;    // by id
  std::set<std::size_t> objects_;  // ranks of the object set's members shown
};

/// Renders one scene's pictures into the batch folder; returns how many failed.
std::size_t renderScene(const fs::path& dir, const report::SceneRecord& scene,
                        std::vector<PictureJob>& jobs, int size, ProgressBar& progress) {
  TriangleMesh mesh;
  try {
    mesh = report::readSceneMesh(dir / "collection", scene);
  } catch (const std::exception& e) {
    log::warning(std::string("collection page: no pictures of a scene: ") + e.what());
    progress.advance(jobs.size());
    return jobs.size();
  }
  std::vector<render::PaintedHypothesis> objects;
  for (const PictureJob& job : jobs) {
    if (job.rank > 0) objects.push_back({job.rank, job.score, job.vertices, true});
  }
  render::SnapshotView view;
  std::optional<render::SnapshotRenderer> ranked;
  try {
    view = render::overviewView(mesh, nullptr, objects, 4 * size, 3 * size,
                                render::ViewKind::kThreeQuarter);
    if (!objects.empty()) ranked.emplace(mesh, objects);
  } catch (const std::exception& e) {
    log::warning(std::string("collection page: no pictures of a scene: ") + e.what());
    progress.advance(jobs.size());
    return jobs.size();
  }
  std::size_t failed = 0, object = 0;
  for (PictureJob& job : jobs) {
    try {
      cv::Mat bgr;
      if (job.rank > 0) {
        bgr = ranked->closeUp(object++, view, size, size).bgr;
      } else {
        // On its own: a segment may overlap another shown from the same scene.
        render::PaintedHypothesis one{1, job.score, job.vertices, false};
        one.show_rank = false;
        render::SnapshotRenderer alone(mesh, {one});
        bgr = alone.closeUp(0, view, size, size).bgr;
      }
      writeFileAtomically(dir / job.file, encodePng(bgr));
      for (CollectionItem* item : job.items) item->picture = job.file;
    } catch (const std::exception& e) {
      log::warning("collection page: " + job.file + " not rendered: " + e.what());
      ++failed;
    }
    progress.advance();
  }
  return failed;
}

}  // namespace

CollectionPageOutcome writeCollectionPage(const fs::path& dir,
                                          const std::vector<CollectionRecording>& recordings,
                                          const CollectionPageOptions& options) {
  const auto start = SteadyClock::now();
  PageBuilder builder(dir, recordings, options);
  builder.addGroups();
  std::map<std::size_t, std::vector<PictureJob>> jobs = builder.pictureJobs();
  std::error_code ec;
  fs::remove_all(dir / kPictureFolder, ec);  // an earlier batch's pictures
  fs::create_directories(dir / kPictureFolder, ec);
  if (ec) throw OutputError(dir / kPictureFolder, "cannot be made: " + ec.message());
  std::size_t total = 0;
  for (const auto& [scene, list] : jobs) total += list.size();
  CollectionPageOutcome out;
  ProgressBar progress("collection pictures", total);
  for (auto& [scene, list] : jobs) {
    out.pictures_failed +=
        renderScene(dir, builder.scene(scene), list, options.picture_size, progress);
  }
  out.pictures = total - out.pictures_failed;
  out.page = report::writeCollectionPage(builder.page(), dir / "index.html");
  out.scenes = builder.page().scenes.size();
  out.groups = builder.page().groups.size();
  out.seconds = secondsSince(start);
  return out;
}

}  // namespace objscan::pipeline
