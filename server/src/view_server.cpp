#include "objscan/server/view_server.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <utility>

#include <nlohmann/json.hpp>

#include "http_query.h"
#include "objscan/core/byte_writing.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/palette.h"
#include "objscan/core/progress.h"
#include "objscan/report/mesh_view.h"
#include "objscan/report/results_io.h"
#include "view_page.h"  // generated from view_page.html: kViewPage

namespace objscan::server {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

/// Labels as the page names them.
constexpr std::array<const char*, 3> kLabelNames = {"not_object", "object", "unsure"};

Json labelJson(const std::optional<int>& label) {
  if (!label || *label < 0 || *label > 2) return nullptr;
  return kLabelNames[static_cast<std::size_t>(*label)];
}

Json measuresJson(const discovery::ShapeMeasures& m) {
  Json j = Json::object();
  const auto values = discovery::measureValues(m);
  for (std::size_t k = 0; k < values.size(); ++k) {
    j[discovery::kMeasureNames[k]] = std::isfinite(values[k]) ? Json(values[k]) : Json(nullptr);
  }
  return j;
}

Json vectorJson(const Eigen::Vector3f& v) { return Json::array({v.x(), v.y(), v.z()}); }

std::string dump(const Json& j) { return j.dump(-1, ' ', false, Json::error_handler_t::replace); }

HttpReply jsonError(int status, const std::string& message) {
  return HttpReply::json(dump(Json{{"error", message}}), status);
}

/// A vertex list as the page reads it (a Uint32Array): little-endian uint32s.
std::string u32Bytes(const std::vector<std::uint32_t>& values) {
  std::string out;
  out.reserve(values.size() * 4);
  for (const std::uint32_t v : values) byte_writing::putLittleEndian(out, v);
  return out;
}

/// A whole decimal number in `text` (no sign, no spaces), or nothing.
std::optional<std::int64_t> wholeNumber(std::string_view text) {
  std::int64_t value = 0;
  if (text.empty() || text.size() > 18) return std::nullopt;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < 0) return std::nullopt;
  return value;
}

/// Who labels: the page's name when it gives one, else (no "by", or null) the server's; nothing
/// when the page's is not a name (discovery::labellerNameProblem says why: `problem`).
std::optional<std::string> labellerOf(const Json& body, const std::string& fallback,
                                      std::string* problem) {
  const auto it = body.find("by");
  if (it == body.end() || it->is_null()) return fallback;
  if (!it->is_string()) {
    *problem = "it is not a string";
    return std::nullopt;
  }
  std::string by = it->get<std::string>();
  *problem = discovery::labellerNameProblem(by);
  if (!problem->empty()) return std::nullopt;
  return by;
}

/// The 400 for a "by" that is not a name.
HttpReply badLabeller(const std::string& problem) {
  return jsonError(400, "\"by\" is not a labeller's name: " + problem);
}

/// A POST's body as a JSON object, or nothing (then `error` is the 400 to answer).
std::optional<Json> objectBody(const HttpRequest& request, HttpReply* error) {
  Json body = Json::parse(request.body, nullptr, false);
  if (body.is_discarded() || !body.is_object()) {
    *error = jsonError(400, "the body is not a JSON object");
    return std::nullopt;
  }
  return body;
}

Json eventJson(const discovery::LabelEvent& e) {
  Json j = {{"event", e.id},
            {"segment", e.segment_id},
            {"label", labelJson(e.label)},
            {"previous", labelJson(e.previous)},
            {"by", e.by},
            {"at", e.at}};
  if (e.undoes) j["undoes"] = *e.undoes;
  return j;
}

Json countsJson(const discovery::LabelCounts& c) {
  return {{"segments", c.segments},
          {"labelled", c.labelled},
          {"objects", c.objects},
          {"not_objects", c.not_objects},
          {"unsure", c.unsure}};
}

}  // namespace

// ---- ViewData ----------------------------------------------------------------------------------

ViewData::ViewData(const ViewSettings& settings) : settings_(settings) {
  hypotheses_ = report::readHypotheses(settings.dir / report::kHypothesesFile);
  if (hypotheses_.scenes.empty()) {
    throw InputError(settings.dir / report::kHypothesesFile, "lists no scene: nothing to show");
  }
  if (settings.catalog) {
    catalog_path_ = *settings.catalog;
  } else if (hypotheses_.catalog && !hypotheses_.catalog->path.empty()) {
    catalog_path_ = hypotheses_.catalog->path;
  }
  std::error_code ec;
  if (catalog_path_.empty()) {
    labelling_off_ =
        "the results were made without a catalog (--no-catalog): labels live in a catalog; run "
        "discover with --catalog, or give view --catalog";
  } else if (const fs::file_status status = fs::status(catalog_path_, ec);
             status.type() != fs::file_type::regular) {
    // A folder, a FIFO or a device is there, not a catalog: "missing" would send one looking.
    labelling_off_ = "the catalog " + catalog_path_.string() +
                     (status.type() == fs::file_type::not_found ? " is missing"
                      : status.type() == fs::file_type::directory
                          ? " is a folder, not a catalog file"
                          : " is not a regular file (a pipe or a device?), not a catalog");
  } else if (fs::file_size(catalog_path_, ec) == 0 || ec) {
    // SQLite would make an empty file a new catalog: not the viewer's to do.
    labelling_off_ = "the catalog " + catalog_path_.string() + " is empty";
  } else {
    try {
      catalog_ = std::make_unique<discovery::Catalog>(catalog_path_);
      if (!catalog_->writable()) {
        catalog_.reset();
        labelling_off_ = "the catalog " + catalog_path_.string() + " is write-protected";
      }
    } catch (const std::exception& e) {
      labelling_off_ = e.what();
    }
  }
  if (!labelling_off_.empty()) log::warning("labelling is off: " + labelling_off_);

  const fs::path camera = settings.dir / "renders" / "overview_camera.json";
  if (fs::is_regular_file(camera, ec)) {
    try {
      camera_json_ = report::viewCameraJson(report::readOverviewCamera(camera));
      if (camera_json_ == "null") camera_json_.clear();
    } catch (const std::exception& e) {  // the view starts from its own camera instead
      log::warning(std::string("the overview camera is not used: ") + e.what());
    }
  }
}

void ViewData::loadScenes() {
  scenes_.resize(hypotheses_.scenes.size());
  ProgressBar progress("reading scenes", scenes_.size());
  for (std::size_t i = 0; i < scenes_.size(); ++i) {
    loadScene(i, scenes_[i]);
    progress.advance();
  }
  progress.finish();
  ready_ = true;
}

void ViewData::loadScene(std::size_t index, ViewScene& scene) {
  const report::SceneRecord& record = hypotheses_.scenes[index];
  scene.name = record.mesh;
  fs::path mesh_file;
  TriangleMesh mesh;
  std::vector<std::int32_t> vertex_map;  // full mesh -> preview
  try {
    mesh = report::readSceneMesh(settings_.dir, record, &mesh_file);
    if (mesh.triangles.empty()) throw InputError(mesh_file, "has no triangles to show");
    const report::ViewMesh view = report::viewMesh(mesh, hypotheses_.hypotheses, record.mesh,
                                                   settings_.max_preview_triangles);
    scene.payload = std::make_shared<const std::string>(report::meshViewPayload(view));
    scene.vertices = mesh.positions.size();
    scene.faces = mesh.triangles.size();
    scene.preview_vertices = view.preview.mesh.positions.size();
    scene.preview_faces = view.preview.mesh.triangles.size();
    for (const report::HypothesisRecord& h : hypotheses_.hypotheses) {
      if (h.scene == record.mesh) {
        scene.hypothesis_vertices.emplace_back(
            h.rank, report::previewVertices(view.preview.vertex_map, h.vertices));
      }
    }
    vertex_map = view.preview.vertex_map;
  } catch (const std::exception& e) {
    scene.error = e.what();  // said by runView: a warning, or the error when no scene can be shown
    return;
  }
  if (catalog_) findInCatalog(record, mesh_file, vertex_map, scene);
}

void ViewData::findInCatalog(const report::SceneRecord& record, const fs::path& mesh_file,
                             const std::vector<std::int32_t>& vertex_map, ViewScene& scene) {
  std::optional<std::int64_t> id;
  try {
    // Hypotheses are candidates that survived suppression: the same vertex lists. The scene the
    // labels go to must hold them, whatever the catalog says of its ids.
    std::map<std::vector<std::int32_t>, std::size_t> rank_of;
    for (const report::HypothesisRecord& h : hypotheses_.hypotheses) {
      if (h.scene == record.mesh && !h.vertices.empty()) rank_of.emplace(h.vertices, h.rank);
    }
    const auto holds = [&](const std::vector<discovery::CatalogSegment>& segments) {
      std::size_t found = 0;
      for (const discovery::CatalogSegment& c : segments) found += rank_of.count(c.vertices);
      return found;
    };
    // Among the catalog's scenes of this mesh's content and size (its id noted in hypotheses.json
    // means something only in the catalog the run used), the one that holds the most of the
    // hypotheses; the noted one, then the newest, on a tie.
    // A copy discover wrote (a PCD view, a frame) is known to the catalog by its source's hash.
    const std::string hash = !record.mesh_copy.empty() && !record.content_hash.empty()
                                 ? record.content_hash
                                 : discovery::contentHash(mesh_file);
    const bool same_catalog =
        hypotheses_.catalog && fs::path(hypotheses_.catalog->path) == catalog_path_;
    std::size_t best = 0;
    std::vector<discovery::CatalogSegment> chosen;  // the chosen scene's, with their vertices
    for (const discovery::CatalogScene& s : catalog_->scenesWithHash(hash)) {
      if (s.vertex_count != scene.vertices) continue;
      std::vector<discovery::CatalogSegment> segments = catalog_->segments(s.id, true);
      const std::size_t n =
          holds(segments) * 2 + (same_catalog && record.catalog_scene == s.id ? 1 : 0);
      if (!id || n >= best) {
        id = s.id;
        best = n;
        chosen = std::move(segments);
      }
    }
    if (!id) {
      scene.label_error = "the catalog " + catalog_path_.string() + " does not hold this scene " +
                          "(run discover on it with --catalog " + catalog_path_.string() + ")";
      log::warning("scene " + record.mesh + " cannot be labelled: " + scene.label_error);
      return;
    }
    for (const discovery::CatalogSegment& c : chosen) {
      ViewScene::Segment s;
      s.id = c.id;
      s.scale = c.scale;
      s.vertex_count = c.vertices.size();
      s.measures = c.measures;
      if (const auto it = rank_of.find(c.vertices); it != rank_of.end()) s.rank = it->second;
      for (const std::int32_t v : c.vertices) {
        if (v < 0 || static_cast<std::size_t>(v) >= scene.vertices) {
          throw InputError(catalog_path_,
                           "segment " + std::to_string(c.id) + " names a vertex outside its scene");
        }
      }
      s.preview = report::previewVertices(vertex_map, c.vertices);
      scene.segments.push_back(std::move(s));
    }
    std::stable_sort(scene.segments.begin(), scene.segments.end(),
                     [](const ViewScene::Segment& a, const ViewScene::Segment& b) {
                       const std::size_t ra = a.rank ? a.rank : SIZE_MAX;
                       const std::size_t rb = b.rank ? b.rank : SIZE_MAX;
                       return ra < rb;
                     });
    scene.catalog_scene = id;
  } catch (const std::exception& e) {
    scene.label_error = e.what();
    scene.segments.clear();
    log::warning("scene " + record.mesh + " cannot be labelled: " + scene.label_error);
  }
}

// ---- ViewServer --------------------------------------------------------------------------------

ViewServer::ViewServer(ViewData& data, const ServeAddress& address)
    : data_(data),
      server_(
          address, [this](const HttpRequest& request) { return route(request); },
          HttpServerOptions{"--serve", 4096, false}) {}

HttpReply ViewServer::route(const HttpRequest& request) {
  const std::string_view path = request.path;
  if (request.method == "POST") {
    if (path != "/api/label" && path != "/api/undo") {
      return jsonError(405, "POST is taken only by /api/label and /api/undo");
    }
    if (!data_.ready()) return jsonError(503, "still reading the scenes: ask again in a moment");
    return path == "/api/label" ? label(request) : undo(request);
  }
  if (path == "/" || path == "/index.html") {
    return HttpReply::staticBytes("text/html; charset=utf-8", kViewPage);
  }
  constexpr const char* kScript = "text/javascript; charset=utf-8";
  if (path == "/assets/three.min.js") return HttpReply::staticBytes(kScript, report::threeJs());
  if (path == "/assets/OrbitControls.js") {
    return HttpReply::staticBytes(kScript, report::orbitControlsJs());
  }
  if (path == "/assets/mesh_view.js") return HttpReply::staticBytes(kScript, report::meshViewJs());
  if (!data_.ready()) return jsonError(503, "still reading the scenes: ask again in a moment");
  if (path == "/api/results") {
    const report::Hypotheses& h = data_.hypotheses();
    Json scenes = Json::array();
    std::map<std::string, std::size_t> scene_index;
    for (std::size_t i = 0; i < data_.scenes().size(); ++i) {
      const ViewScene& s = data_.scenes()[i];
      scene_index.emplace(s.name, i);
      Json j = {{"index", i},
                {"name", s.name},
                {"vertices", s.vertices},
                {"faces", s.faces},
                {"preview_vertices", s.preview_vertices},
                {"preview_faces", s.preview_faces},
                {"decimated", s.preview_faces < s.faces},
                {"labelling", s.catalog_scene.has_value()}};
      if (!s.error.empty()) j["error"] = s.error;
      if (!s.label_error.empty()) j["label_error"] = s.label_error;
      if (s.catalog_scene) j["catalog_scene"] = *s.catalog_scene;
      scenes.push_back(j);
    }
    Json hypotheses = Json::array();
    for (const report::HypothesisRecord& r : h.hypotheses) {
      Json j = {{"rank", r.rank},
                {"scene", scene_index.count(r.scene) ? Json(scene_index[r.scene]) : Json(nullptr)},
                {"score", r.score ? Json(*r.score) : Json(nullptr)},
                // Only the object set's members have the object score they are ranked by.
                {"object_score",
                 r.objectScoreIfObject() ? Json(*r.objectScoreIfObject()) : Json(nullptr)},
                {"footing", r.footing.empty() ? Json(nullptr) : Json(r.footing)},
                {"measures", measuresJson(r.measures)},
                {"vertex_count", r.vertex_count.value_or(r.vertices.size())},
                {"scale", r.scale ? Json(*r.scale) : Json(nullptr)}};
      if (!r.file.empty()) j["file"] = r.file;
      if (r.box) {
        j["box"] = {
            {"centre", vectorJson(r.box->centre)},
            {"extents", vectorJson(r.box->extents)},
            {"axes", Json::array({vectorJson(r.box->axes.col(0)), vectorJson(r.box->axes.col(1)),
                                  vectorJson(r.box->axes.col(2))})}};
      }
      hypotheses.push_back(j);
    }
    Json palette = Json::array();
    for (const auto& c : kRankPalette) palette.push_back({c[0], c[1], c[2]});
    Json doc = {{"folder", data_.settings().dir.string()},
                {"scenes", scenes},
                {"hypotheses", hypotheses},
                {"palette", palette},
                {"labeller", data_.settings().labeller},
                {"painted_top", report::paintedTop(data_.settings().dir)},
                {"catalog", data_.catalogPath().string()}};
    if (!data_.cameraJson().empty()) doc["camera"] = Json::parse(data_.cameraJson());
    if (h.scoring) doc["scoring"] = {{"kind", h.scoring->kind}, {"model", h.scoring->model}};
    if (!data_.labellingOff().empty()) doc["labelling_off"] = data_.labellingOff();
    return HttpReply::json(dump(doc));
  }
  constexpr std::string_view kScenes = "/api/scenes/";
  if (path.substr(0, kScenes.size()) == kScenes) {
    const std::string_view rest = path.substr(kScenes.size());
    const std::size_t slash = rest.find('/');
    const std::optional<std::int64_t> index = wholeNumber(rest.substr(0, slash));
    if (!index || static_cast<std::size_t>(*index) >= data_.scenes().size()) {
      return jsonError(404, "no such scene");
    }
    const ViewScene& scene = data_.scenes()[static_cast<std::size_t>(*index)];
    if (slash == std::string_view::npos) return jsonError(404, "not found");
    return sceneRoute(request, scene, rest.substr(slash + 1));
  }
  constexpr std::string_view kResults = "/results/";
  if (path.substr(0, kResults.size()) == kResults) {
    const fs::path file = resultFile(data_.settings().dir, path.substr(kResults.size()));
    if (file.empty()) return HttpReply::text(404, "no such file in the results folder");
    return HttpReply::sendFile(file);
  }
  return HttpReply::text(404, "not found");
}

HttpReply ViewServer::sceneRoute(const HttpRequest& request, const ViewScene& scene,
                                 std::string_view rest) {
  if (!scene.error.empty()) return jsonError(404, "this scene cannot be shown: " + scene.error);
  if (rest == "mesh") return HttpReply::sharedBytes("application/octet-stream", scene.payload);
  constexpr std::string_view kHypotheses = "hypotheses/", kSegments = "segments/";
  const auto numberBefore = [](std::string_view text, std::string_view suffix) {
    if (text.size() <= suffix.size() || text.substr(text.size() - suffix.size()) != suffix) {
      return std::optional<std::int64_t>();
    }
    return wholeNumber(text.substr(0, text.size() - suffix.size()));
  };
  if (rest.substr(0, kHypotheses.size()) == kHypotheses) {
    const auto rank = numberBefore(rest.substr(kHypotheses.size()), "/vertices");
    for (const auto& [r, vertices] : scene.hypothesis_vertices) {
      if (rank && static_cast<std::int64_t>(r) == *rank) {
        return HttpReply::bytes("application/octet-stream", u32Bytes(vertices));
      }
    }
    return jsonError(404, "no such hypothesis in this scene");
  }
  if (rest.substr(0, kSegments.size()) == kSegments) {
    const auto id = numberBefore(rest.substr(kSegments.size()), "/vertices");
    for (const ViewScene::Segment& s : scene.segments) {
      if (id && s.id == *id)
        return HttpReply::bytes("application/octet-stream", u32Bytes(s.preview));
    }
    return jsonError(404, "no such segment in this scene");
  }
  if (!scene.catalog_scene) {
    return jsonError(409,
                     "this scene cannot be labelled: " +
                         (scene.label_error.empty() ? data_.labellingOff() : scene.label_error));
  }
  if (rest == "at") {
    const std::optional<std::string> value = queryValue(request.query, "vertex", 31);
    const std::optional<std::int64_t> vertex =
        value && !value->empty() ? wholeNumber(*value) : std::nullopt;
    if (!vertex || static_cast<std::uint64_t>(*vertex) >= scene.preview_vertices) {
      return jsonError(400, "give ?vertex=N, a vertex of the preview mesh (0 to " +
                                std::to_string(scene.preview_vertices) + " - 1)");
    }
    std::vector<std::pair<std::size_t, std::int64_t>> found;  // (size, id)
    for (const ViewScene::Segment& s : scene.segments) {
      if (std::binary_search(s.preview.begin(), s.preview.end(),
                             static_cast<std::uint32_t>(*vertex))) {
        found.emplace_back(s.vertex_count, s.id);
      }
    }
    std::sort(found.begin(), found.end());
    Json ids = Json::array();
    for (const auto& f : found) ids.push_back(f.second);
    return HttpReply::json(dump(Json{{"segments", ids}}));
  }
  if (rest == "segments" || rest == "labels") {
    std::vector<discovery::CatalogSegment> rows;
    discovery::LabelCounts counts;
    {
      std::lock_guard<std::mutex> lock(data_.catalogMutex());
      rows = data_.catalog()->segments(*scene.catalog_scene, false);
      counts = data_.catalog()->labelCounts(*scene.catalog_scene);
    }
    std::map<std::int64_t, const discovery::CatalogSegment*> by_id;
    for (const discovery::CatalogSegment& c : rows) by_id[c.id] = &c;
    Json list = Json::array();
    for (const ViewScene::Segment& s : scene.segments) {
      const auto it = by_id.find(s.id);
      const discovery::CatalogSegment* c = it == by_id.end() ? nullptr : it->second;
      Json j = {{"id", s.id},
                {"label", c ? labelJson(c->label) : Json(nullptr)},
                {"by", c ? c->labelled_by : std::string()},
                {"at", c ? c->labelled_at : std::string()}};
      if (rest == "segments") {
        j["rank"] = s.rank ? Json(s.rank) : Json(nullptr);
        j["scale"] = s.scale;
        j["vertex_count"] = s.vertex_count;
        j["measures"] = measuresJson(s.measures);
      }
      list.push_back(j);
    }
    return HttpReply::json(dump(Json{{"segments", list}, {"progress", countsJson(counts)}}));
  }
  return jsonError(404, "not found");
}

HttpReply ViewServer::label(const HttpRequest& request) {
  HttpReply refused;
  const std::optional<Json> parsed = objectBody(request, &refused);
  if (!parsed) return refused;
  const Json& body = *parsed;
  const auto segment = body.find("segment");
  if (segment == body.end() || !segment->is_number_integer()) {
    return jsonError(400, "give \"segment\": the id of a candidate segment");
  }
  std::optional<int> value;
  const auto given = body.find("label");
  if (given == body.end())
    return jsonError(400, "give \"label\": object, not_object, unsure or null");
  if (!given->is_null()) {
    const std::string name = given->is_string() ? given->get<std::string>() : std::string();
    for (std::size_t k = 0; k < kLabelNames.size(); ++k) {
      if (name == kLabelNames[k]) value = static_cast<int>(k);
    }
    if (!value) return jsonError(400, "a label is object, not_object, unsure or null");
  }
  std::string problem;
  const std::optional<std::string> by = labellerOf(body, data_.settings().labeller, &problem);
  if (!by) return badLabeller(problem);
  const auto id = segment->get<std::int64_t>();
  // Only segments of the scenes shown: the page labels what it shows.
  const ViewScene* owner = nullptr;
  for (const ViewScene& s : data_.scenes()) {
    for (const ViewScene::Segment& seg : s.segments) {
      if (seg.id == id) owner = &s;
    }
  }
  if (!data_.catalog()) return jsonError(409, "labelling is off: " + data_.labellingOff());
  if (!owner || !owner->catalog_scene) return jsonError(404, "no such segment among these scenes");
  std::lock_guard<std::mutex> lock(data_.catalogMutex());
  try {
    const discovery::LabelEvent e = data_.catalog()->setLabel(id, value, *by);
    Json j = eventJson(e);
    j["progress"] = countsJson(data_.catalog()->labelCounts(*owner->catalog_scene));
    return HttpReply::json(dump(j));
  } catch (const std::invalid_argument& e) {
    // The label and name were checked: the segment has gone (its scene was replaced since).
    return jsonError(409, e.what());
  } catch (const std::exception& e) {
    log::warning(std::string("a label could not be stored: ") + e.what());
    return jsonError(503, std::string("the label was not stored: ") + e.what());
  }
}

HttpReply ViewServer::undo(const HttpRequest& request) {
  HttpReply refused;
  const std::optional<Json> parsed = objectBody(request, &refused);
  if (!parsed) return refused;
  const Json& body = *parsed;
  const auto event = body.find("event");
  if (event == body.end() || !event->is_number_integer()) {
    return jsonError(400, "give \"event\": the id of the label event to undo");
  }
  std::string problem;
  const std::optional<std::string> by = labellerOf(body, data_.settings().labeller, &problem);
  if (!by) return badLabeller(problem);
  if (!data_.catalog()) return jsonError(409, "labelling is off: " + data_.labellingOff());
  const auto id = event->get<std::int64_t>();
  std::lock_guard<std::mutex> lock(data_.catalogMutex());
  try {
    // Only events of the scenes shown: the page undoes what it labelled.
    std::optional<discovery::LabelEvent> found;
    for (const ViewScene& s : data_.scenes()) {
      if (!s.catalog_scene || found) continue;
      for (const discovery::LabelEvent& e : data_.catalog()->labelEvents(*s.catalog_scene)) {
        if (e.id == id) found = e;
      }
    }
    if (!found) return jsonError(404, "no such label event among these scenes");
    // An undo takes back one's own label, never somebody else's.
    if (found->by != *by) {
      return jsonError(409, "that label was made by " + found->by + ", not by " + *by +
                                ": label the segment again instead");
    }
    const discovery::LabelEvent e = data_.catalog()->undoLabel(id, *by);
    Json j = eventJson(e);
    j["progress"] = countsJson(data_.catalog()->labelCounts(e.scene_id));
    return HttpReply::json(dump(j));
  } catch (const discovery::LabelConflict& e) {
    return jsonError(409, e.what());
  } catch (const std::invalid_argument& e) {
    return jsonError(404, e.what());
  } catch (const std::exception& e) {
    log::warning(std::string("an undo could not be stored: ") + e.what());
    return jsonError(503, std::string("the undo was not stored: ") + e.what());
  }
}

}  // namespace objscan::server
