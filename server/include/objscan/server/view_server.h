#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "objscan/discovery/catalog.h"
#include "objscan/report/results.h"
#include "objscan/server/http_server.h"

/// `objscan view`: a results folder in 3-D in the browser, and the paper's labelling tool.
namespace objscan::server {

struct ViewSettings {
  std::filesystem::path dir;  ///< the results folder (hypotheses.json)
  /// The catalog labels go to; nothing: the one hypotheses.json names.
  std::optional<std::filesystem::path> catalog;
  std::string labeller;  ///< who labels, when the page does not say
  /// Meshes with more triangles are shown decimated to this many (vertex clustering).
  std::size_t max_preview_triangles = 1'000'000;
};

/// One scene of the folder as the page shows it.
struct ViewScene {
  std::string name;   ///< SceneRecord::mesh
  std::string error;  ///< why it cannot be shown (its mesh is missing or damaged); empty when fine
  std::size_t vertices = 0, faces = 0, preview_vertices = 0, preview_faces = 0;
  std::shared_ptr<const std::string> payload;  ///< report::meshViewPayload
  /// Per hypothesis of this scene (by rank), its vertices on the preview.
  std::vector<std::pair<std::size_t, std::vector<std::uint32_t>>> hypothesis_vertices;
  /// The scene in the labelling catalog; nothing: it cannot be labelled (`label_error` says why).
  std::optional<std::int64_t> catalog_scene;
  std::string label_error;
  struct Segment {
    std::int64_t id = 0;
    float scale = 0.0f;
    std::size_t vertex_count = 0;
    discovery::ShapeMeasures measures;
    std::size_t rank = 0;                ///< the hypothesis it is, 0 when it is none
    std::vector<std::uint32_t> preview;  ///< its vertices on the preview, increasing
  };
  std::vector<Segment> segments;  ///< the catalog's candidates: ranked ones first, by rank
};

/// The folder, read once at start: hypotheses.json (required), each scene's mesh (an error for a
/// scene whose mesh cannot be read is kept and shown, not thrown), and the catalog's candidates.
class ViewData {
 public:
  /// Reads hypotheses.json, the overview's camera and opens the catalog. Throws InputError when
  /// DIR holds no results (no or a damaged hypotheses.json).
  explicit ViewData(const ViewSettings& settings);
  /// Reads every scene's mesh and candidates (the long part: the server answers "not yet" till
  /// then). Call once, before scenes().
  void loadScenes();
  bool ready() const { return ready_.load(); }

  const ViewSettings& settings() const { return settings_; }
  const report::Hypotheses& hypotheses() const { return hypotheses_; }
  const std::vector<ViewScene>& scenes() const { return scenes_; }
  /// The catalog labels go to (empty when none), and why labelling is off (empty when on).
  const std::filesystem::path& catalogPath() const { return catalog_path_; }
  const std::string& labellingOff() const { return labelling_off_; }
  /// The overview picture's camera as JSON (report::viewCameraJson), the first scene's starting
  /// view; empty when the folder has none.
  const std::string& cameraJson() const { return camera_json_; }

  /// The catalog, for one caller at a time: lock catalogMutex() around every use.
  discovery::Catalog* catalog() { return catalog_.get(); }
  std::mutex& catalogMutex() { return catalog_mutex_; }

 private:
  void loadScene(std::size_t index, ViewScene& scene);
  /// The scene's candidates in the catalog; `vertex_map` takes the full mesh's vertices to the
  /// preview's (DecimatedMesh::vertex_map).
  void findInCatalog(const report::SceneRecord& record, const std::filesystem::path& mesh_file,
                     const std::vector<std::int32_t>& vertex_map, ViewScene& scene);

  ViewSettings settings_;
  report::Hypotheses hypotheses_;
  std::vector<ViewScene> scenes_;
  std::filesystem::path catalog_path_;
  std::string labelling_off_;
  std::string camera_json_;
  std::unique_ptr<discovery::Catalog> catalog_;
  std::mutex catalog_mutex_;
  std::atomic<bool> ready_{false};
};

/// The viewer's routes, on http_server.h's server:
///   GET  /                                   the page
///   GET  /assets/{three.min.js,OrbitControls.js,mesh_view.js}
///   GET  /api/results                        scenes, hypotheses, scoring, labelling state
///   GET  /api/scenes/I/mesh                  the preview mesh (report::meshViewPayload)
///   GET  /api/scenes/I/hypotheses/R/vertices its vertices on the preview (uint32 LE)
///   GET  /api/scenes/I/segments              the candidates with their labels and progress
///   GET  /api/scenes/I/segments/ID/vertices  its vertices on the preview (uint32 LE)
///   GET  /api/scenes/I/at?vertex=V           the candidates on preview vertex V, smallest first
///   GET  /api/scenes/I/labels                labels and progress (polled: other tabs' labels)
///   POST /api/label  {"segment": ID, "label": "object"|"not_object"|"unsure"|null, "by": NAME}
///   POST /api/undo   {"event": ID, "by": NAME}   409 when the label changed since
///   GET  /results/NAME                       a file of the results folder, read-only
class ViewServer {
 public:
  /// Starts serving `data`: before data.ready() the API answers 503 (the page waits and asks
  /// again).
  ViewServer(ViewData& data, const ServeAddress& address);
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;
  const std::string& url() const { return server_.url(); }

 private:
  HttpReply route(const HttpRequest& request);
  HttpReply sceneRoute(const HttpRequest& request, const ViewScene& scene, std::string_view rest);
  HttpReply label(const HttpRequest& request);
  HttpReply undo(const HttpRequest& request);

  ViewData& data_;
  HttpServer server_;  ///< last: it stops before the data it serves is gone
};

}  // namespace objscan::server
