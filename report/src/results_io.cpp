#include "objscan/report/results_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string_view>
#include <system_error>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "json_node.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/file_names.h"
#include "objscan/core/mesh_orientation.h"
#include "objscan/core/output_folder.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"

namespace objscan::report {
namespace {

namespace fs = std::filesystem;
using json_node::Json;
using json_node::Node;

/// JSON is UTF-8: a path that is not (a folder named in Latin-1) is written with U+FFFD in place
/// of its stray bytes rather than failing the run at its last step.
std::string jsonText(const Json& doc) {
  return doc.dump(1, ' ', false, Json::error_handler_t::replace) + "\n";
}

/// writeJson for a file in a staging folder (writeStagedFile).
void writeStagedJson(const fs::path& file, const Json& doc) {
  writeStagedFile(file, jsonText(doc));
}

void writeJson(const fs::path& file, const Json& doc) { writeFileAtomically(file, jsonText(doc)); }

Json vectorJson(const Eigen::Vector3f& v) { return {v.x(), v.y(), v.z()}; }

/// A box as hypotheses.json and objects/rank_NNN.json hold it: centre, axes as rows, extents.
Json boxJson(const OrientedBox& box) {
  return {{"centre", vectorJson(box.centre)},
          {"axes",
           {vectorJson(box.axes.col(0)), vectorJson(box.axes.col(1)), vectorJson(box.axes.col(2))}},
          {"extents", vectorJson(box.extents)}};
}

/// null: unknown (recurrence without another scene to compare with).
Json measuresJson(const discovery::ShapeMeasures& m) {
  Json j;
  const auto values = discovery::measureValues(m);
  for (std::size_t k = 0; k < values.size(); ++k) {
    j[discovery::kMeasureNames[k]] = std::isfinite(values[k]) ? Json(values[k]) : Json(nullptr);
  }
  return j;
}

discovery::ShapeMeasures measuresFrom(const std::optional<Node>& node) {
  std::array<double, discovery::kMeasureCount> v;
  v.fill(NAN);
  if (node) {
    for (std::size_t k = 0; k < v.size(); ++k) {
      v[k] = node->number(discovery::kMeasureNames[k]).value_or(NAN);
    }
  }
  discovery::ShapeMeasures m;
  m.compactness = v[0];
  m.symmetry = v[1];
  m.smoothness = v[2];
  m.local_convexity = v[3];
  m.global_convexity = v[4];
  m.recurrence = v[5];
  return m;
}

OrientedBox boxOf(const TriangleMesh& mesh, const discovery::Segment& s) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
  for (std::int32_t v : s.vertices) {
    const Eigen::Vector3f p = s.axes.transpose() * (mesh.positions[v] - s.centroid);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  OrientedBox box;
  box.centre = s.centroid + s.axes * (0.5f * (lo + hi));
  box.axes = s.axes;
  box.extents = hi - lo;
  return box;
}

Eigen::Vector3f vector3(const std::vector<double>& v) {
  return Eigen::Vector3f(static_cast<float>(v[0]), static_cast<float>(v[1]),
                         static_cast<float>(v[2]));
}

std::optional<OrientedBox> boxFrom(const std::optional<Node>& node) {
  if (!node) return std::nullopt;
  OrientedBox box;
  if (const auto c = node->numbers("centre", 3)) box.centre = vector3(*c);
  if (const auto e = node->numbers("extents", 3)) box.extents = vector3(*e);
  if (const Json* axes = node->get("axes")) {
    if (!axes->is_array() || axes->size() != 3) node->fail(node->keyPath("axes"), "is not 3 axes");
    for (int k = 0; k < 3; ++k) {
      box.axes.col(k) = vector3(node->numbersIn((*axes)[k], node->keyPath("axes"), 3));
    }
  }
  return box;
}

}  // namespace

std::string exactText(float value) {
  char text[32];
  // The fewest digits that read back to the same float; 9 always do.
  for (int digits = 6; digits <= 9; ++digits) {
    std::snprintf(text, sizeof text, "%.*g", digits, static_cast<double>(value));
    if (std::strtof(text, nullptr) == value) break;
  }
  return text;
}

std::string writeMeshAndTrajectory(const std::filesystem::path& dir, const TriangleMesh& mesh,
                                   const Trajectory& trajectory) {
  std::string bytes = encodePly(mesh);
  writeFileAtomically(dir / kMeshFile, bytes);
  writeTumTrajectory(dir / kTrajectoryFile, trajectory);
  return bytes;
}

void removeOutputsAfterTheMesh(const std::filesystem::path& dir) {
  for (const char* name : {kHypothesesFile, kObjectsFolder, kRendersFolder, kEvaluationFile,
                           kReportFile, kTimingsFile, kSettingsFile}) {
    std::error_code ec;
    if (std::filesystem::exists(dir / name, ec)) {
      std::filesystem::remove_all(dir / name, ec);
      if (ec) {
        throw OutputError(dir / name, "cannot remove an earlier run's output: " + ec.message());
      }
    }
  }
}

std::string rankFileName(std::size_t rank, const char* extension) {
  char name[48];
  std::snprintf(name, sizeof name, "rank_%03zu%s", rank, extension);
  return name;
}

// ---- hypotheses.json ---------------------------------------------------------------------------

std::optional<CatalogUse> catalogUseOf(const discovery::SceneDiscovery& run) {
  if (!run.catalog) return std::nullopt;
  // Absolute: objscan view and a repeated run find it from any working directory.
  std::error_code ec;
  const fs::path absolute = fs::absolute(*run.catalog, ec).lexically_normal();
  return CatalogUse{(ec ? *run.catalog : absolute).string(), run.catalog_scenes,
                    run.catalog_segments};
}

namespace {

/// objects/rank_NNN.json: what one object file needs beside it to be placed in the scene.
Json objectPoseJson(const HypothesisRecord& h) {
  OrientedBox box = *h.box;
  if (box.axes.determinant() < 0.0f) box.axes.col(2) = -box.axes.col(2);  // right-handed
  Json pose = Json::array();
  for (int r = 0; r < 4; ++r) {
    Json row = Json::array();
    for (int c = 0; c < 4; ++c) {
      row.push_back(r == 3 ? (c == 3 ? 1.0f : 0.0f) : c == 3 ? box.centre[r] : box.axes(r, c));
    }
    pose.push_back(row);
  }
  Json j = {{"rank", h.rank},
            {"scene", h.scene},
            {"mesh", fs::path(h.file).filename().string()},
            {"vertex_count", h.vertex_count.value_or(h.vertices.size())},
            {"frame",
             "T_W_O maps the object frame (origin at the box centre, axes along the box's, "
             "right-handed) to the scene mesh's world frame; metres; rows of a 4x4 matrix"},
            {"T_W_O", pose},
            {"box", boxJson(box)}};
  if (h.score) j["score"] = *h.score;
  return j;
}

/// Each object's mesh file and pose file into the staging folder `partial`.
void writeObjects(const fs::path& partial, const Hypotheses& hypotheses,
                  const discovery::SceneDiscovery& run, MeshFormat format) {
  // glTF is Y-up: each scene's up (as the overview picture finds it), for the GLB's node.
  std::vector<std::optional<Eigen::Vector3f>> ups(run.scenes.size());
  if (format == MeshFormat::kGlb) {
    for (std::size_t s = 0; s < run.scenes.size(); ++s) {
      try {
        ups[s] = sceneUp(run.scenes[s].mesh);
      } catch (const std::invalid_argument&) {  // no face of any area: no up to turn
      }
    }
  }
  std::vector<std::optional<MeshSubsets>> parts(run.scenes.size());
  for (std::size_t i = 0; i < run.ranked.size(); ++i) {
    const std::size_t scene = run.ranked[i].scene;
    if (!parts[scene]) parts[scene].emplace(run.scenes[scene].mesh);
    const HypothesisRecord& h = hypotheses.hypotheses.at(i);
    const fs::path file = partial / fs::path(h.file).filename();
    writeStagedFile(
        file, encodeMesh(parts[scene]->subset(run.ranked[i].hypothesis.segment.vertices), format,
                         ups[scene]));
    if (h.box) writeStagedJson(partial / rankFileName(h.rank, ".json"), objectPoseJson(h));
  }
}

/// Whether discovery's scene `name` is a PLY file that view and render can read again as it is
/// (not a PCD view, whose points become a mesh as it is read, nor "<source>@frameN").
bool isPlyFile(const std::string& name) {
  std::error_code ec;
  return lowercaseExtension(name) == ".ply" && fs::is_regular_file(name, ec);
}

/// The copies of the scenes that are not PLY files into the staging folder `partial`.
void writeSceneCopies(const fs::path& partial, const Hypotheses& hypotheses,
                      const discovery::SceneDiscovery& run) {
  for (std::size_t i = 0; i < run.scenes.size() && i < hypotheses.scenes.size(); ++i) {
    const std::string& copy = hypotheses.scenes[i].mesh_copy;
    if (copy.empty()) continue;
    writeStagedFile(partial / fs::path(copy).filename(),
                    encodeMesh(run.scenes[i].mesh, MeshFormat::kPly));
  }
}

/// `name` relative to `results_dir` and absolute when it names a file; as it is otherwise.
std::pair<std::string, std::string> sceneReference(const std::string& name,
                                                   const fs::path& results_dir) {
  std::error_code ec;
  if (!fs::is_regular_file(name, ec)) return {name, {}};
  const fs::path absolute = fs::absolute(name, ec).lexically_normal();
  if (ec) return {name, {}};
  const fs::path relative =
      absolute.lexically_relative(fs::absolute(results_dir, ec).lexically_normal());
  if (ec || relative.empty()) return {absolute.string(), absolute.string()};
  return {relative.string(), absolute.string()};
}

}  // namespace

Hypotheses hypothesesFrom(const discovery::SceneDiscovery& run, const std::string& model,
                          const fs::path& results_dir, MeshFormat object_format) {
  Hypotheses out;
  out.scoring = Scoring{discovery::toString(run.scorer), model, run.normalised_over};
  out.catalog = catalogUseOf(run);
  for (const discovery::DiscoveredScene& scene : run.scenes) {
    SceneRecord r;
    std::tie(r.mesh, r.mesh_absolute) = sceneReference(scene.name, results_dir);
    r.vertices = scene.mesh.positions.size();
    r.faces = scene.mesh.triangles.size();
    r.candidates = scene.candidates.segments.size();
    r.hypotheses = scene.hypotheses;
    r.from_catalog = scene.from_catalog;
    if (!isPlyFile(scene.name)) {
      char copy[32];
      std::snprintf(copy, sizeof copy, "scene_%03zu.ply", out.scenes.size() + 1);
      r.mesh_copy = std::string(kScenesFolder) + "/" + copy;
      r.content_hash = scene.content_hash;
    }
    if (run.catalog) r.catalog_scene = scene.scene_id;
    if (!scene.from_catalog) {
      const discovery::DiscoveryTimings& t = scene.candidates.timings;
      r.findings =
          SceneFindings{scene.candidates.effective.median_edge_m,
                        scene.candidates.effective.min_size,
                        scene.candidates.support_planes,
                        scene.candidates.support_vertices,
                        {t.graph_ms, t.support_ms, t.segment_ms, t.filter_ms, t.measure_ms}};
    }
    out.scenes.push_back(std::move(r));
  }
  for (std::size_t i = 0; i < run.ranked.size(); ++i) {
    const discovery::DiscoveredScene& scene = run.scenes[run.ranked[i].scene];
    const discovery::Hypothesis& h = run.ranked[i].hypothesis;
    HypothesisRecord r;
    r.rank = i + 1;
    r.score = h.score;
    r.scene = out.scenes[run.ranked[i].scene].mesh;
    r.measures = h.measures;
    r.box = boxOf(scene.mesh, h.segment);
    r.scale = h.segment.scale;
    r.vertices = h.segment.vertices;
    r.vertex_count = h.segment.vertices.size();
    r.file =
        std::string(kObjectsFolder) + "/" + rankFileName(i + 1, extensionOf(object_format).c_str());
    if (std::isfinite(h.object_score)) {
      r.object_rank = h.object_rank;
      r.object_score = h.object_score;
    }
    r.footing = discovery::toString(h.context.footing);
    const auto known = [](double v) { return std::isfinite(v) ? std::optional(v) : std::nullopt; };
    r.height_m = known(h.context.height_m);
    r.share_of_region = h.context.share_of_region;
    r.observation = known(h.context.observation);
    r.rise_m = known(h.context.rise_m);
    r.support_noise_m = known(h.context.support_noise_m);
    r.covered_share = known(h.context.covered_share);
    out.hypotheses.push_back(std::move(r));
  }
  return out;
}

void writeDiscovery(const fs::path& dir, const Hypotheses& hypotheses,
                    const discovery::SceneDiscovery& run, MeshFormat format) {
  const bool copies = std::any_of(hypotheses.scenes.begin(), hypotheses.scenes.end(),
                                  [](const SceneRecord& s) { return !s.mesh_copy.empty(); });
  const fs::path partial = freshPartialFolder(dir, kObjectsFolder);
  try {
    writeObjects(partial, hypotheses, run, format);
    if (copies) writeSceneCopies(freshPartialFolder(dir, kScenesFolder), hypotheses, run);
  } catch (...) {
    std::error_code ec;
    // A failed run leaves the old objects/ and scenes/, and nothing half-made.
    fs::remove_all(partial, ec);
    fs::remove_all(dir / (std::string(kScenesFolder) + ".partial"), ec);
    throw;
  }
  writeHypotheses(dir / kHypothesesFile, hypotheses);
  swapInFolder(dir, kObjectsFolder);
  if (copies) {
    swapInFolder(dir, kScenesFolder);
  } else {
    std::error_code ec;
    fs::remove_all(dir / kScenesFolder, ec);  // an earlier run's copies, named by nothing now
  }
}

void writeHypotheses(const fs::path& file, const Hypotheses& hyp) {
  Json doc;
  if (hyp.scoring) {
    doc["scoring"] = {
        {"kind", hyp.scoring->kind},
        {"model", hyp.scoring->model.empty() ? Json(nullptr) : Json(hyp.scoring->model)},
        {"normalised_over", hyp.scoring->normalised_over}};
  }
  if (hyp.catalog) {
    doc["catalog"] = {{"path", hyp.catalog->path},
                      {"scenes", hyp.catalog->scenes},
                      {"segments", hyp.catalog->segments}};
  }
  Json scenes = Json::array();
  for (const SceneRecord& s : hyp.scenes) {
    Json j = {{"mesh", s.mesh}, {"from_catalog", s.from_catalog}};
    if (!s.mesh_absolute.empty()) j["mesh_absolute"] = s.mesh_absolute;
    if (!s.mesh_copy.empty()) j["mesh_copy"] = s.mesh_copy;
    if (!s.content_hash.empty()) j["content_hash"] = s.content_hash;
    if (s.catalog_scene) j["catalog_scene"] = *s.catalog_scene;
    if (s.vertices) j["vertices"] = *s.vertices;
    if (s.faces) j["faces"] = *s.faces;
    if (s.candidates) j["candidates"] = *s.candidates;
    if (s.hypotheses) j["hypotheses"] = *s.hypotheses;
    if (s.findings) {
      const SceneFindings& f = *s.findings;
      j["median_edge_m"] = f.median_edge_m;
      j["min_size"] = f.min_size;
      j["support_planes"] = f.support_planes;
      j["support_vertices"] = f.support_vertices;
      j["timings_ms"] = {{"graph", f.timings_ms.graph},
                         {"supports", f.timings_ms.supports},
                         {"segmentation", f.timings_ms.segmentation},
                         {"filters", f.timings_ms.filters},
                         {"measures", f.timings_ms.measures}};
    }
    scenes.push_back(j);
  }
  doc["scenes"] = scenes;
  Json list = Json::array();
  for (const HypothesisRecord& h : hyp.hypotheses) {
    Json j = {{"rank", h.rank},
              {"scene", h.scene},
              {"measures", measuresJson(h.measures)},
              {"vertex_count", h.vertex_count.value_or(h.vertices.size())},
              {"vertices", h.vertices},
              {"file", h.file}};
    if (h.score) j["score"] = *h.score;
    if (h.scale) j["scale"] = *h.scale;
    if (h.object_rank) {
      j["object_set"] = *h.object_rank > 0;
      if (*h.object_rank > 0) j["object_rank"] = *h.object_rank;
    }
    if (h.object_score) j["object_score"] = *h.object_score;
    if (!h.footing.empty()) {
      Json c = {{"footing", h.footing}};
      c["height_m"] = h.height_m ? Json(*h.height_m) : Json(nullptr);
      if (h.share_of_region) c["share_of_region"] = *h.share_of_region;
      c["observation"] = h.observation ? Json(*h.observation) : Json(nullptr);
      c["rise_m"] = h.rise_m ? Json(*h.rise_m) : Json(nullptr);
      c["support_noise_m"] = h.support_noise_m ? Json(*h.support_noise_m) : Json(nullptr);
      c["covered_share"] = h.covered_share ? Json(*h.covered_share) : Json(nullptr);
      j["context"] = c;
    }
    if (h.box) {
      j["box"] = boxJson(*h.box);
    }
    list.push_back(j);
  }
  doc["hypotheses"] = list;
  writeJson(file, doc);
}

Hypotheses readHypotheses(const fs::path& file) {
  if (!fs::exists(file)) {
    throw InputError(file,
                     "missing: run `objscan discover` or `objscan scan` into this folder first");
  }
  const Json doc = json_node::parseFile(file);
  const Node top(file, doc, "");
  if (top.get("hypotheses") == nullptr) top.fail("hypotheses", "is missing");
  Hypotheses out;
  if (const std::optional<Node> s = top.object("scoring")) {
    out.scoring = Scoring{s->string("kind").value_or(""), s->string("model").value_or(""),
                          s->string("normalised_over").value_or("")};
  }
  if (const std::optional<Node> c = top.object("catalog")) {
    out.catalog = CatalogUse{c->string("path").value_or(""), c->count("scenes").value_or(0),
                             c->count("segments").value_or(0)};
  }
  for (const Node& s : top.objects("scenes")) {
    SceneRecord r;
    r.mesh = s.require("mesh", s.string("mesh"));
    r.mesh_absolute = s.string("mesh_absolute").value_or("");
    r.mesh_copy = s.string("mesh_copy").value_or("");
    r.content_hash = s.string("content_hash").value_or("");
    r.vertices = s.count("vertices");
    r.faces = s.count("faces");
    r.candidates = s.count("candidates");
    r.hypotheses = s.count("hypotheses");
    r.from_catalog = s.boolean("from_catalog").value_or(false);
    if (const Json* id = s.get("catalog_scene"); id && id->is_number_integer()) {
      r.catalog_scene = id->get<std::int64_t>();
    }
    if (const std::optional<Node> t = s.object("timings_ms")) {
      r.findings =
          SceneFindings{s.number("median_edge_m").value_or(NAN),
                        s.count("min_size").value_or(0),
                        s.count("support_planes").value_or(0),
                        s.count("support_vertices").value_or(0),
                        {t->number("graph").value_or(0), t->number("supports").value_or(0),
                         t->number("segmentation").value_or(0), t->number("filters").value_or(0),
                         t->number("measures").value_or(0)}};
    }
    out.scenes.push_back(std::move(r));
  }
  for (const Node& h : top.objects("hypotheses")) {
    HypothesisRecord r;
    const std::optional<std::int64_t> rank = h.integer("rank");
    if (!rank || *rank < 1) h.fail(h.keyPath("rank"), "is missing or not a rank (1, 2, ...)");
    r.rank = static_cast<std::size_t>(*rank);
    r.score = h.number("score");
    r.scene = h.string("scene").value_or("");
    r.measures = measuresFrom(h.object("measures"));
    r.box = boxFrom(h.object("box"));
    if (const std::optional<double> scale = h.number("scale")) r.scale = static_cast<float>(*scale);
    if (const Json* v = h.get("vertices")) {
      if (!v->is_array()) h.fail(h.keyPath("vertices"), "is not an array of vertex indices");
      r.vertices.reserve(v->size());
      for (const Json& e : *v) {
        if (!e.is_number_integer() || e.get<std::int64_t>() < 0 ||
            e.get<std::int64_t>() > INT32_MAX) {
          h.fail(h.keyPath("vertices"), "holds something that is not a vertex index");
        }
        r.vertices.push_back(e.get<std::int32_t>());
      }
    }
    r.vertex_count = h.count("vertex_count");
    r.file = h.string("file").value_or("");
    if (const std::optional<bool> in_set = h.boolean("object_set")) {
      r.object_rank = *in_set ? h.count("object_rank").value_or(0) : 0;
      if (*in_set && r.object_rank == 0u) {
        h.fail(h.keyPath("object_rank"), "is missing or not a rank (1, 2, ...) of an object");
      }
    }
    r.object_score = h.number("object_score");
    if (const std::optional<Node> c = h.object("context")) {
      r.footing = c->string("footing").value_or("");
      r.height_m = c->number("height_m");
      r.share_of_region = c->number("share_of_region");
      r.observation = c->number("observation");
      r.rise_m = c->number("rise_m");
      r.support_noise_m = c->number("support_noise_m");
      r.covered_share = c->number("covered_share");
    }
    out.hypotheses.push_back(std::move(r));
  }
  for (std::size_t i = 0; i < out.hypotheses.size(); ++i) {
    const std::string& scene = out.hypotheses[i].scene;
    const bool listed = std::any_of(out.scenes.begin(), out.scenes.end(),
                                    [&](const SceneRecord& s) { return s.mesh == scene; });
    if (!listed) {
      top.fail("hypotheses[" + std::to_string(i) + "].scene",
               "names a scene that \"scenes\" does not list");
    }
  }
  std::stable_sort(
      out.hypotheses.begin(), out.hypotheses.end(),
      [](const HypothesisRecord& a, const HypothesisRecord& b) { return a.rank < b.rank; });
  return out;
}

// ---- evaluation.json ---------------------------------------------------------------------------

Evaluation evaluationFrom(const discovery::RankingEvaluation& e, const std::string& ground_truth,
                          const std::map<std::int32_t, std::string>& names) {
  Evaluation out;
  out.ground_truth = ground_truth;
  out.objects = e.objects;
  out.found = e.found;
  out.min_iou = e.min_iou;
  out.ap = e.ap;
  for (std::size_t k = 0; k < e.ranks.size(); ++k) {
    const discovery::RankMatch& m = e.ranks[k];
    const auto name = names.find(m.match.object_id);
    out.ranks.push_back({k + 1, m.match.object_id,
                         m.match.object_id != 0 && name != names.end() ? name->second : "",
                         m.match.iou, m.found, m.ignored, m.precision, m.recall});
  }
  return out;
}

void writeEvaluation(const fs::path& file, const Evaluation& e) {
  Json curve = Json::array(), matches = Json::array();
  for (const EvaluatedRank& r : e.ranks) {
    curve.push_back({{"rank", r.rank}, {"recall", r.recall}, {"precision", r.precision}});
    matches.push_back({{"rank", r.rank},
                       {"object_id", r.object_id},
                       {"object", r.object.empty() ? Json(nullptr) : Json(r.object)},
                       {"iou", r.iou},
                       {"found", r.found},
                       {"ignored", r.ignored}});
  }
  writeJson(file, {{"ground_truth", e.ground_truth},
                   {"objects", e.objects ? Json(*e.objects) : Json(nullptr)},
                   {"min_iou", e.min_iou},
                   {"found", e.found ? Json(*e.found) : Json(nullptr)},
                   {"ap", e.ap},
                   {"curve", curve},
                   {"hypotheses", matches}});
}

Evaluation readEvaluation(const fs::path& file) {
  const Json doc = json_node::parseFile(file);
  const Node top(file, doc, "");
  Evaluation e;
  e.ground_truth = top.string("ground_truth").value_or("");
  e.objects = top.count("objects");
  e.found = top.count("found");
  e.min_iou = top.number("min_iou").value_or(NAN);
  e.ap = top.number("ap").value_or(NAN);
  std::map<std::size_t, EvaluatedRank> by_rank;
  for (const Node& p : top.objects("curve")) {
    const std::optional<std::size_t> rank = p.count("rank");
    if (!rank) continue;
    EvaluatedRank& r = by_rank[*rank];
    r.rank = *rank;
    r.recall = p.number("recall").value_or(NAN);
    r.precision = p.number("precision").value_or(NAN);
  }
  for (const Node& h : top.objects("hypotheses")) {
    const std::optional<std::size_t> rank = h.count("rank");
    if (!rank) continue;
    EvaluatedRank& r = by_rank[*rank];
    r.rank = *rank;
    r.object_id = static_cast<std::int32_t>(h.integer("object_id").value_or(0));
    r.object = h.string("object").value_or("");
    r.iou = h.number("iou").value_or(NAN);
    r.found = h.boolean("found").value_or(r.iou >= e.min_iou);
    r.ignored = h.boolean("ignored").value_or(false);
  }
  for (auto& [rank, r] : by_rank) e.ranks.push_back(r);
  return e;
}

// ---- timings.json ------------------------------------------------------------------------------

void writeTimings(const fs::path& file, const Timings& t) {
  Json stages = Json::array();
  for (const StageTime& s : t.stages) stages.push_back({{"name", s.name}, {"seconds", s.seconds}});
  Json doc = {{"source", t.source},
              {"interrupted", t.interrupted},
              {"stages", stages},
              {"not_produced", t.not_produced}};
  if (t.total_s) doc["total_s"] = *t.total_s;
  if (t.frames) {
    Json f = Json::object();
    const auto put = [&f](const char* key, const std::optional<std::size_t>& v) {
      if (v) f[key] = *v;
    };
    put("read", t.frames->read);
    put("fused", t.frames->fused);
    put("lost", t.frames->lost);
    put("without_depth", t.frames->without_depth);
    put("unreadable", t.frames->unreadable);
    doc["frames"] = f;
  }
  if (t.mesh_vertices || t.mesh_faces) {
    doc["mesh"] = Json::object();
    if (t.mesh_vertices) doc["mesh"]["vertices"] = *t.mesh_vertices;
    if (t.mesh_faces) doc["mesh"]["faces"] = *t.mesh_faces;
  }
  if (t.hypotheses) doc["hypotheses"] = *t.hypotheses;
  if (!t.sensor_lost.empty()) doc["sensor_lost"] = t.sensor_lost;
  writeJson(file, doc);
}

Timings readTimings(const fs::path& file) {
  const Json doc = json_node::parseFile(file);
  const Node top(file, doc, "");
  Timings t;
  t.source = top.string("source").value_or("");
  t.interrupted = top.boolean("interrupted").value_or(false);
  t.not_produced = top.strings("not_produced");
  for (const Node& s : top.objects("stages")) {
    t.stages.push_back({s.string("name").value_or("?"), s.number("seconds").value_or(0.0)});
  }
  t.total_s = top.number("total_s");
  if (const std::optional<Node> f = top.object("frames")) {
    t.frames = FrameCounts{f->count("read"), f->count("fused"), f->count("lost"),
                           f->count("without_depth"), f->count("unreadable")};
  }
  if (const std::optional<Node> m = top.object("mesh")) {
    t.mesh_vertices = m->count("vertices");
    t.mesh_faces = m->count("faces");
  }
  t.hypotheses = top.count("hypotheses");
  t.sensor_lost = top.string("sensor_lost").value_or("");
  return t;
}

// ---- renders/ ----------------------------------------------------------------------------------

Picture pictureFromPng(std::string png, const std::string& what) {
  // 8-byte signature, then the IHDR chunk: length (4), "IHDR", width (4, big-endian), height (4).
  static constexpr std::string_view kSignature("\x89PNG\r\n\x1a\n", 8);
  const std::string_view b = png;
  if (b.size() < 33 || b.substr(0, 8) != kSignature || b.substr(12, 4) != "IHDR") {
    throw InputError(what, "not a PNG image (it should have been written by `objscan render`)");
  }
  auto be32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
    return v;
  };
  Picture p;
  p.width = be32(16);
  p.height = be32(20);
  if (p.width == 0 || p.height == 0) throw InputError(what, "PNG image of size zero");
  p.png = std::move(png);
  return p;
}

namespace {

std::optional<Picture> readPicture(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  return pictureFromPng(readWholeFile(path), path.string());
}

Json cameraJson(const OverviewCamera& c) {
  Json rows = Json::array();
  const Eigen::Matrix4f T = c.T_W_C.matrix();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  const Intrinsics& in = c.intrinsics;
  return {{"view", c.view},
          {"T_W_C", rows},
          {"intrinsics",
           {{"fx", in.fx_px},
            {"fy", in.fy_px},
            {"cx", in.cx_px},
            {"cy", in.cy_px},
            {"width", in.width_px},
            {"height", in.height_px}}}};
}

}  // namespace

std::size_t paintedTop(const fs::path& dir) {
  std::error_code ec;
  std::size_t painted = 0;
  while (fs::is_regular_file(dir / kRendersFolder / rankFileName(painted + 1, ".png"), ec)) {
    ++painted;
  }
  return painted > 0 ? painted : kDefaultPaintedTop;
}

OverviewCamera readOverviewCamera(const fs::path& file) {
  const Json doc = json_node::parseFile(file);
  const Node top(file, doc, "");
  OverviewCamera c;
  c.view = top.string("view").value_or("");
  const Json* rows = top.get("T_W_C");
  if (rows == nullptr || !rows->is_array() || rows->size() != 4) top.fail("T_W_C", "is not 4 rows");
  Eigen::Matrix4f T;
  for (int r = 0; r < 4; ++r) {
    const std::vector<double> row = top.numbersIn((*rows)[r], "T_W_C", 4);
    for (int k = 0; k < 4; ++k) T(r, k) = static_cast<float>(row[k]);
  }
  c.T_W_C.matrix() = T;
  const Node in = top.require("intrinsics", top.object("intrinsics"));
  c.intrinsics.fx_px = in.require("fx", in.number("fx"));
  c.intrinsics.fy_px = in.require("fy", in.number("fy"));
  c.intrinsics.cx_px = in.require("cx", in.number("cx"));
  c.intrinsics.cy_px = in.require("cy", in.number("cy"));
  c.intrinsics.width_px = static_cast<int>(in.require("width", in.integer("width")));
  c.intrinsics.height_px = static_cast<int>(in.require("height", in.integer("height")));
  return c;
}

namespace {

}  // namespace

void writePictures(const fs::path& dir, const Pictures& pictures) {
  const fs::path partial = freshPartialFolder(dir, kRendersFolder);
  // Whatever stops the writing, the staging folder goes: renders/ stays as it was.
  struct RemoveUnlessSwapped {
    fs::path path;
    bool swapped = false;
    ~RemoveUnlessSwapped() {
      std::error_code ec;
      if (!swapped) fs::remove_all(path, ec);
    }
  } staging{partial};
  if (pictures.camera) {
    writeStagedJson(partial / "overview_camera.json", cameraJson(*pictures.camera));
  }
  const auto put = [&partial](const char* name, const std::optional<Picture>& p) {
    if (p) writeStagedFile(partial / name, p->png);
  };
  put("overview.png", pictures.overview);
  put("overview_ranks.png", pictures.overview_ranks);
  for (const auto& [rank, p] : pictures.closeups) {
    writeStagedFile(partial / rankFileName(rank, ".png"), p.png);
  }
  put("contact_sheet.png", pictures.contact_sheet);
  swapInFolder(dir, kRendersFolder);
  staging.swapped = true;
}

Pictures readPictures(const fs::path& dir, const std::vector<std::size_t>& ranks) {
  const fs::path renders = dir / kRendersFolder;
  Pictures p;
  p.overview = readPicture(renders / "overview.png");
  p.overview_ranks = readPicture(renders / "overview_ranks.png");
  p.contact_sheet = readPicture(renders / "contact_sheet.png");
  for (std::size_t rank : ranks) {
    if (auto closeup = readPicture(renders / rankFileName(rank, ".png"))) {
      p.closeups[rank] = std::move(*closeup);
    }
  }
  std::error_code ec;
  if (fs::exists(renders / "overview_camera.json", ec)) {
    p.camera = readOverviewCamera(renders / "overview_camera.json");
  }
  return p;
}

// ---- settings.json -----------------------------------------------------------------------------

namespace {

/// A value as JSON: a flag as a boolean; text that is a number written as JSON writes it ("500",
/// "0.03") as that number; any other text ("0001", "1e3", a path) as a string, so that reading
/// it back gives the same text.
Json settingValue(const std::string& text, bool flag) {
  if (flag) return text == "true" || text == "1";
  try {
    const Json number = Json::parse(text);
    if (number.is_number() && number.dump() == text) return number;
  } catch (const Json::exception&) {
  }
  return text;
}

std::string settingText(const Node& where, const std::string& name, const Json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  if (v.is_number()) return v.dump();
  where.fail(where.keyPath(name.c_str()), "is neither text, a number nor true/false");
}

Json settingsJson(const std::vector<OptionSetting>& settings) {
  Json options = Json::object();
  for (const OptionSetting& o : settings) {
    if (o.list) {
      Json values = Json::array();
      for (const std::string& v : o.values) values.push_back(settingValue(v, o.flag));
      options[o.name] = values;
    } else if (!o.values.empty()) {
      options[o.name] = settingValue(o.values.front(), o.flag);
    } else {
      options[o.name] = nullptr;
    }
  }
  return options;
}

std::vector<OptionSetting> settingsFrom(const Node& options) {
  std::vector<OptionSetting> out;
  for (const auto& [name, value] : options.json().items()) {
    OptionSetting o;
    o.name = name;
    o.flag = value.is_boolean();
    if (value.is_array()) {
      o.list = true;
      for (const Json& v : value) o.values.push_back(settingText(options, name, v));
    } else if (!value.is_null()) {
      o.values.push_back(settingText(options, name, value));
    }
    out.push_back(std::move(o));
  }
  return out;
}

}  // namespace

void writeSettings(const fs::path& file, const Settings& s) {
  Json doc = {{"objscan_version", s.objscan_version},
              {"command", s.command},
              {"options", settingsJson(s.options)}};
  if (!s.resolved.empty()) doc["resolved"] = settingsJson(s.resolved);
  if (s.intrinsics) {
    const Intrinsics& in = *s.intrinsics;
    doc["intrinsics"] = {{"fx", in.fx_px},
                         {"fy", in.fy_px},
                         {"cx", in.cx_px},
                         {"cy", in.cy_px},
                         {"width", in.width_px},
                         {"height", in.height_px},
                         {"origin", s.intrinsics_origin}};
  }
  doc["catalog"] = s.catalog ? Json{{"path", s.catalog->path},
                                    {"scenes", s.catalog->scenes},
                                    {"segments", s.catalog->segments}}
                             : Json(nullptr);
  writeJson(file, doc);
}

Settings readSettings(const fs::path& file) {
  return parseSettings(readWholeFile(file, kMaxSettingsBytes), file);
}

Settings parseSettings(const std::string& text, const fs::path& file) {
  const Json doc = json_node::parseText(text, file);
  const Node top(file, doc, "");
  Settings s;
  s.objscan_version = top.string("objscan_version").value_or("");
  s.command = top.require("command", top.string("command"));
  s.options = settingsFrom(top.require("options", top.object("options")));
  if (const std::optional<Node> resolved = top.object("resolved"))
    s.resolved = settingsFrom(*resolved);
  if (const std::optional<Node> in = top.object("intrinsics")) {
    Intrinsics i;
    i.fx_px = in->require("fx", in->number("fx"));
    i.fy_px = in->require("fy", in->number("fy"));
    i.cx_px = in->require("cx", in->number("cx"));
    i.cy_px = in->require("cy", in->number("cy"));
    i.width_px = static_cast<int>(in->require("width", in->integer("width")));
    i.height_px = static_cast<int>(in->require("height", in->integer("height")));
    s.intrinsics = i;
    s.intrinsics_origin = in->string("origin").value_or("");
  }
  if (const std::optional<Node> c = top.object("catalog")) {
    s.catalog = CatalogUse{c->string("path").value_or(""), c->count("scenes").value_or(0),
                           c->count("segments").value_or(0)};
  }
  return s;
}

// ---- the folder --------------------------------------------------------------------------------

ScanResults readResults(const fs::path& dir, const ResultsParts& parts) {
  if (!fs::is_directory(dir)) throw InputError(dir, fs::exists(dir) ? "not a folder" : "missing");
  ScanResults r;
  std::error_code ec;
  const auto present = [&](const char* name) { return fs::exists(dir / name, ec); };
  r.hypotheses = readHypotheses(dir / kHypothesesFile);
  if (parts.mesh && present(kMeshFile)) r.mesh = readPly(dir / kMeshFile);
  if (present(kTrajectoryFile)) r.trajectory = readTumTrajectory(dir / kTrajectoryFile);
  if (present(kEvaluationFile)) r.evaluation = readEvaluation(dir / kEvaluationFile);
  if (present(kTimingsFile)) r.timings = readTimings(dir / kTimingsFile);
  if (present(kSettingsFile)) r.settings = readSettings(dir / kSettingsFile);
  if (!parts.pictures) return r;
  std::vector<std::size_t> ranks;
  for (const HypothesisRecord& h : r.hypotheses->hypotheses) {
    if (ranks.size() == parts.max_closeups) break;
    ranks.push_back(h.rank);
  }
  r.pictures = readPictures(dir, ranks);
  return r;
}

}  // namespace objscan::report

namespace objscan::report {

std::vector<fs::path> sceneMeshPlaces(const fs::path& dir, const SceneRecord& scene) {
  std::vector<fs::path> places;
  // Only inside the folder: a relative name without '..', so that mesh_copy cannot send the
  // reader elsewhere (mesh and mesh_absolute name the scene's own file, wherever it is).
  if (const fs::path copy(scene.mesh_copy);
      !copy.empty() && copy.is_relative() &&
      std::none_of(copy.begin(), copy.end(), [](const fs::path& part) { return part == ".."; })) {
    places.push_back(dir / copy);
  }
  places.push_back(dir / kMeshFile);
  const fs::path noted(scene.mesh);
  places.push_back(noted.is_relative() ? dir / noted : noted);
  if (!scene.mesh_absolute.empty()) {
    places.emplace_back(scene.mesh_absolute);
  } else if (noted.is_relative()) {
    places.push_back(noted);
  }
  return places;
}

TriangleMesh readSceneMesh(const fs::path& dir, const SceneRecord& scene, fs::path* found) {
  const std::vector<fs::path> places = sceneMeshPlaces(dir, scene);
  std::optional<InputError> mismatch;
  std::error_code ec;
  std::optional<fs::path> not_ply;
  for (const fs::path& place : places) {
    if (!fs::is_regular_file(place, ec)) continue;
    if (lowercaseExtension(place) != ".ply") {
      if (!not_ply) not_ply = place;  // a PCD view or the like, from before the copies
      continue;
    }
    TriangleMesh mesh = readPly(place);
    if (scene.vertices && mesh.positions.size() == *scene.vertices) {
      if (found) *found = place;
      return mesh;
    }
    if (!mismatch) {
      mismatch.emplace(place, "has " + std::to_string(mesh.positions.size()) +
                                  " vertices, but hypotheses.json was made from a mesh of " +
                                  (scene.vertices ? std::to_string(*scene.vertices)
                                                  : std::string("unknown size")) +
                                  " (run discover again)");
    }
  }
  if (mismatch) throw *mismatch;
  if (not_ply) {
    throw InputError(*not_ply,
                     scene.mesh_copy.empty()
                         ? "is not a PLY file, and the results folder holds no copy of the mesh "
                           "made from it (made by an older objscan): run objscan discover again"
                         : "is not a PLY file, and the copy of the mesh made from it, " +
                               (dir / scene.mesh_copy).string() +
                               ", is missing: run objscan discover again");
  }
  std::string list;
  for (const fs::path& place : places) {
    if (place != dir / kMeshFile) list += (list.empty() ? "" : " or ") + place.string();
  }
  throw InputError(dir / kMeshFile,
                   "missing: the scene mesh hypotheses.json was made from (mesh.ply in the "
                   "results folder, or " +
                       list + ")");
}

}  // namespace objscan::report
