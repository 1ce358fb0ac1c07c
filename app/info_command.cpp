#include "info_command.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <set>
#include <string>

#include "objscan/capture/folder_source.h"
#include "objscan/capture/oni_container.h"
#include "objscan/capture/openni.h"
#include "objscan/capture/seven_scenes_folder.h"
#include "objscan/capture/tum_folder.h"
#include "objscan/core/error.h"
#include "objscan/core/file_names.h"
#include "objscan/core/mesh_formats.h"
#include "objscan/core/organized_cloud.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/progress.h"
#include "objscan/core/trajectory.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/scoring.h"
#include "objscan/discovery/shape_measures.h"
#include "objscan/report/results_io.h"

namespace objscan::app {
namespace fs = std::filesystem;

namespace {

/// A mesh larger than this in any direction is probably not in metres.
constexpr float kSuspiciousExtent_m = 50.0f;

void row(const char* key, const std::string& value) {
  std::printf("%-13s %s\n", key, value.c_str());
}

std::string fmt(const char* format, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, format, args...);
  return buf;
}

std::string vec(const Eigen::Vector3f& v) { return fmt("(%.4f, %.4f, %.4f)", v.x(), v.y(), v.z()); }

std::string bytesText(std::uintmax_t bytes) {
  if (bytes >= 10u << 20) return fmt("%.1f MB", static_cast<double>(bytes) / (1 << 20));
  if (bytes >= 10u << 10) return fmt("%.1f KB", static_cast<double>(bytes) / (1 << 10));
  return fmt("%ju bytes", bytes);
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

void describeBounds(const Eigen::AlignedBox3f& box) {
  row("bounds", "min " + vec(box.min()) + " m, max " + vec(box.max()) + " m");
  const Eigen::Vector3f e = box.sizes();
  row("extent", fmt("%.4f x %.4f x %.4f m", e.x(), e.y(), e.z()));
  if (e.maxCoeff() > kSuspiciousExtent_m) {
    row("note",
        "larger than 50 m: objscan expects metres; is this file in millimetres or centimetres?");
  }
}

void describeMesh(const fs::path& path) {
  PlyReadReport report;
  const TriangleMesh mesh = readPly(path, &report);
  if (mesh.empty()) throw InputError(path, "contains no vertices (an empty mesh)");
  row("file", path.string());
  row("type", fmt("mesh (PLY %s, %s)", toString(report.header.format),
                  bytesText(report.file_bytes).c_str()));
  row("vertices", fmt("%zu (normals: %s, colours: %s)", mesh.positions.size(),
                      mesh.hasNormals() ? "yes" : "no", mesh.hasColors() ? "yes" : "no"));
  if (mesh.hasLabels()) {
    std::set<std::int32_t> ids(mesh.labels.begin(), mesh.labels.end());
    ids.erase(0);
    const auto labelled = static_cast<std::size_t>(std::count_if(
        mesh.labels.begin(), mesh.labels.end(), [](std::int32_t l) { return l != 0; }));
    // The reader takes the ids from `object_id` or, in a hand-labelled mesh, `label`.
    std::string id_property = "object_id";
    for (const PlyHeader::Element& e : report.header.elements) {
      if (e.name != "vertex") continue;
      for (const PlyHeader::Property& p : e.properties) {
        if (p.name == "label") id_property = "label";
      }
    }
    row("objects", fmt("%zu object ids on %zu vertices (%s; 0 = not an object)", ids.size(),
                       labelled, id_property.c_str()));
  }
  if (mesh.hasWeights()) {
    const auto [lo, hi] = std::minmax_element(mesh.weights.begin(), mesh.weights.end());
    row("weights", fmt("%.4g .. %.4g (quality: the fusion weight, observations)", *lo, *hi));
  }
  if (mesh.hasIgnore()) {
    const auto skipped = static_cast<std::size_t>(
        std::count_if(mesh.ignore.begin(), mesh.ignore.end(), [](std::uint8_t f) { return f; }));
    row("not scored", fmt("%zu vertices (ignore = 1)", skipped));
  }
  if (report.faces == 0) {
    row("faces", "0 (a point cloud)");
  } else if (report.faces == mesh.triangles.size()) {
    row("faces", fmt("%zu triangles", report.faces));
  } else {
    row("faces", fmt("%zu polygons -> %zu triangles (%zu degenerate dropped)", report.faces,
                     mesh.triangles.size(), report.degenerate_dropped));
  }
  describeBounds(mesh.bounds());
  if (!mesh.triangles.empty()) row("area", fmt("%.4f m^2", mesh.surfaceArea()));
  if (!report.ignored.empty()) row("ignored", joined(report.ignored));
  if (!report.header.comments.empty()) row("comments", joined(report.header.comments));
}

void describeTrajectory(const fs::path& path) {
  const Trajectory trajectory = readTumTrajectory(path);
  row("file", path.string());
  row("type", "trajectory (TUM format: t tx ty tz qx qy qz qw, camera-to-world)");
  row("poses", std::to_string(trajectory.size()));
  const double duration = trajectory.durationS();
  row("time",
      fmt("%.6f .. %.6f s (%.2f s%s)", trajectory.poses.front().stamp_s,
          trajectory.poses.back().stamp_s, duration,
          duration > 0 ? fmt(", %.1f Hz mean", (trajectory.size() - 1) / duration).c_str() : ""));
  row("path", fmt("%.3f m travelled", trajectory.pathLengthM()));
  Eigen::AlignedBox3f box;
  for (const auto& p : trajectory.poses) box.extend(p.T_W_C.translation());
  row("positions", "min " + vec(box.min()) + " m, max " + vec(box.max()) + " m");
}

/// Statistics over the valid depth readings of all frames; the median comes from a 1 mm histogram.
struct DepthSummary {
  std::size_t pixels = 0;
  std::size_t valid = 0;
  float min_m = INFINITY;
  float max_m = 0.0f;
  std::vector<std::size_t> histogram_mm = std::vector<std::size_t>(20000, 0);

  void add(const cv::Mat& depth_m) {
    for (int v = 0; v < depth_m.rows; ++v) {
      const float* rowp = depth_m.ptr<float>(v);
      for (int u = 0; u < depth_m.cols; ++u) {
        const float d = rowp[u];
        ++pixels;
        if (!(d > 0.0f) || !std::isfinite(d)) continue;
        ++valid;
        min_m = std::min(min_m, d);
        max_m = std::max(max_m, d);
        ++histogram_mm[std::min<std::size_t>(static_cast<std::size_t>(d * 1000.0f),
                                             histogram_mm.size() - 1)];
      }
    }
  }

  double medianM() const {
    std::size_t seen = 0;
    for (std::size_t mm = 0; mm < histogram_mm.size(); ++mm) {
      seen += histogram_mm[mm];
      if (2 * seen >= valid) return (static_cast<double>(mm) + 0.5) / 1000.0;
    }
    return 0.0;
  }
};

void describeTumFolder(const fs::path& path) {
  const capture::TumFolder folder(path);
  // Decode every frame before printing anything, so a bad image leaves no half report.
  DepthSummary summary;
  std::size_t with_colour = 0;
  {
    ProgressBar progress("reading frames", folder.size());
    for (std::size_t i = 0; i < folder.size(); ++i) {
      const RgbdFrame frame = folder.load(i);
      summary.add(frame.depth_m);
      with_colour += frame.color_rgb.empty() ? 0 : 1;
      progress.advance();
    }
  }

  row("file", path.string());
  row("type", "recording (TUM RGB-D folder)");
  row("frames", fmt("%zu (paired by %s)", folder.size(), folder.associationSource().c_str()));
  const double duration =
      folder.frames().back().depth_stamp_s - folder.frames().front().depth_stamp_s;
  if (folder.size() > 1 && duration > 0) {
    row("time", fmt("%.2f s, %.1f Hz mean", duration, (folder.size() - 1) / duration));
  }
  const Intrinsics& in = folder.intrinsics();
  row("intrinsics",
      fmt("fx %.1f fy %.1f cx %.1f cy %.1f, %dx%d px (%s)", in.fx_px, in.fy_px, in.cx_px, in.cy_px,
          in.width_px, in.height_px,
          folder.intrinsicsFromFile() ? "intrinsics.json" : "Xtion defaults: no intrinsics.json"));
  row("depth units", fmt("raw value / %g = metres", folder.depthFactor()));
  if (folder.groundTruth()) {
    row("ground truth",
        fmt("%zu poses (%s), %.3f m path", folder.groundTruth()->size(),
            folder.groundTruthSource().c_str(), folder.groundTruth()->pathLengthM()));
  } else {
    row("ground truth", "none");
  }
  row("images", fmt("all %zu frames decoded, %zu with colour", folder.size(), with_colour));
  if (summary.valid == 0) {
    row("depth", "no valid readings in any frame");
  } else {
    row("depth",
        fmt("%.1f %% of pixels valid, %.3f .. %.3f m, median %.3f m",
            100.0 * static_cast<double>(summary.valid) / static_cast<double>(summary.pixels),
            summary.min_m, summary.max_m, summary.medianM()));
  }
}

void describePcd(const fs::path& path) {
  const OrganizedCloud cloud = readPcd(path);
  row("file", path.string());
  row("type", fmt("point cloud (PCD, %s): discover meshes its pixel grid into a scene",
                  bytesText(fs::file_size(path)).c_str()));
  row("points", fmt("%zu, %s (%d x %d), %zu with a reading; colours: %s",
                    cloud.points_C.size(), cloud.organized() ? "organized" : "unorganized",
                    cloud.width, cloud.height, cloud.validCount(),
                    cloud.colors.empty() ? "no" : "yes"));
  if (!cloud.labels.empty()) {
    std::set<std::int32_t> objects;
    for (const std::uint32_t l : cloud.labels) {
      if (const std::int32_t id = objectIdOfLabel(l, true); id > 0) objects.insert(id);
    }
    row("labels", fmt("%zu objects (label field: 0 none, 1..9 surfaces, 10 k + p part p of "
                      "object k)", objects.size()));
  }
  Eigen::AlignedBox3f box;
  for (std::size_t i = 0; i < cloud.points_C.size(); ++i) {
    if (cloud.valid(i)) box.extend(cloud.points_C[i]);
  }
  if (!box.isEmpty()) describeBounds(box);
}

/// An object file objscan writes (--object-format obj, stl or glb).
void describeMeshFile(const fs::path& path) {
  const MeshFileSummary m = summarizeMeshFile(path);
  const char* kinds[] = {"PLY", "Wavefront OBJ", "binary STL", "binary glTF 2.0"};
  row("file", path.string());
  row("type", fmt("mesh (%s, %s)", kinds[static_cast<int>(m.format)],
                  bytesText(fs::file_size(path)).c_str()));
  row("vertices", fmt("%zu (normals: %s, colours: %s)%s", m.vertices, m.normals ? "yes" : "no",
                      m.colours ? "yes" : "no",
                      m.format == MeshFormat::kStl ? "; STL repeats each at every triangle" : ""));
  row("faces", m.triangles == 0 ? std::string("0 (points)")
                                 : fmt("%zu %s", m.triangles,
                                       m.triangles == 1 ? "triangle" : "triangles"));
  if (!m.bounds.isEmpty()) describeBounds(m.bounds);
  if (m.format == MeshFormat::kGlb) {
    if (m.node_rotation) {
      // glTF is Y-up: the node turns the scene's up (as objscan found it) onto +Y.
      const Eigen::Vector3f up = m.node_rotation->conjugate() * Eigen::Vector3f::UnitY();
      row("up", "the node turns " + vec(up) + " (the scene's up, in the file's coordinates) "
                "onto glTF's +Y");
    } else {
      row("up", "no node rotation: +Y of the coordinates is up in a glTF viewer");
    }
  }
}

bool startsWith(const fs::path& path, std::string_view magic) {
  std::ifstream in(path, std::ios::binary);
  std::string head(magic.size(), '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  return in.gcount() == static_cast<std::streamsize>(magic.size()) && head == magic;
}

}  // namespace

/// An objscan catalog (SQLite): its scenes, segments and labels.
static void describeCatalog(const fs::path& path) {
  const discovery::Catalog catalog(path);
  const std::vector<discovery::CatalogScene> scenes = catalog.scenes();
  discovery::LabelCounts labels;
  std::set<std::string> settings;
  for (const discovery::CatalogScene& s : scenes) {
    const discovery::LabelCounts c = catalog.labelCounts(s.id);
    labels.labelled += c.labelled;
    labels.objects += c.objects;
    labels.not_objects += c.not_objects;
    labels.unsure += c.unsure;
    settings.insert(s.settings);
  }
  row("file", path.string());
  row("type", fmt("catalog (objscan, SQLite, schema %d, %s)", discovery::Catalog::kSchemaVersion,
                  bytesText(fs::file_size(path)).c_str()));
  row("scenes", fmt("%zu (measured with %zu %s of discovery settings)", scenes.size(),
                    settings.size(), settings.size() == 1 ? "set" : "sets"));
  row("segments", fmt("%zu", catalog.segmentCount()));
  row("labels", fmt("%zu: %zu object, %zu not, %zu unsure (objscan view; objscan train uses them)",
                    labels.labelled, labels.objects, labels.not_objects, labels.unsure));
  for (std::size_t i = 0; i < std::min<std::size_t>(scenes.size(), 10); ++i) {
    row(i == 0 ? "scene" : "", fmt("#%lld %s, %zu vertices", static_cast<long long>(scenes[i].id),
                                   scenes[i].name.c_str(), scenes[i].vertex_count));
  }
  if (scenes.size() > 10) row("", fmt("... and %zu more", scenes.size() - 10));
}

/// A model file of objscan train.
static void describeModel(const fs::path& path) {
  const discovery::ObjectnessModel model = discovery::ObjectnessModel::load(path);
  std::vector<std::string> measures;
  for (std::size_t i = 0; i < discovery::kMeasureCount; ++i) {
    if (model.mask()[i]) measures.emplace_back(discovery::kMeasureNames[i]);
  }
  row("file", path.string());
  row("type", fmt("objectness model (objscan train: discover --model %s)", path.c_str()));
  row("kind", std::string(discovery::toString(model.kind())) +
                  (model.parameters().empty() ? "" : " (" + model.parameters() + ")"));
  row("measures", joined(measures));
  const double ap = model.crossValidatedAp();
  row("trained", std::isnan(ap) ? std::string("no (the average)")
                                 : fmt("cross-validated AP %.3f on its training segments", ap));
}

/// A results folder of scan or discover (hypotheses.json), and eval's or render's additions.
static void describeResults(const fs::path& dir) {
  report::ResultsParts parts;
  parts.pictures = false;
  const report::ScanResults r = report::readResults(dir, parts);
  const report::Hypotheses& h = *r.hypotheses;
  row("file", dir.string());
  row("type", "results folder (objscan scan or discover; objscan view and render show it)");
  row("scenes", std::to_string(h.scenes.size()));
  for (std::size_t i = 0; i < std::min<std::size_t>(h.scenes.size(), 10); ++i) {
    const report::SceneRecord& s = h.scenes[i];
    row(i == 0 ? "scene" : "",
        s.mesh + (s.vertices ? fmt(", %zu vertices", *s.vertices) : std::string()) +
            (s.mesh_copy.empty() ? "" : " (its mesh: " + s.mesh_copy + ")"));
  }
  if (h.scenes.size() > 10) row("", fmt("... and %zu more", h.scenes.size() - 10));
  row("hypotheses", std::to_string(h.hypotheses.size()));
  if (h.scoring) {
    row("scored by", h.scoring->kind + (h.scoring->model.empty() ? "" : " (" + h.scoring->model + ")") +
                         (h.scoring->normalised_over.empty() ? "" : ", normalised over " + h.scoring->normalised_over));
  }
  row("catalog", h.catalog ? h.catalog->path : std::string("none"));
  if (r.evaluation) {
    row("evaluation", fmt("AP %.3f, %zu of %zu objects found (IoU >= %.2f)", r.evaluation->ap,
                          r.evaluation->found.value_or(0), r.evaluation->objects.value_or(0),
                          r.evaluation->min_iou));
  }
  std::vector<std::string> present;
  std::error_code ec;
  for (const char* name : {report::kMeshFile, report::kTrajectoryFile, report::kObjectsFolder,
                           report::kScenesFolder, report::kRendersFolder, report::kReportFile,
                           report::kTimingsFile, report::kSettingsFile, report::kEvaluationFile}) {
    if (fs::exists(dir / name, ec)) present.emplace_back(name);
  }
  row("holds", joined(present));
}

/// A 7-Scenes folder, as fuse reads it.
static void describeSevenScenesFolder(const fs::path& path) {
  const std::unique_ptr<capture::FrameSource> source = capture::openFolderSource(path);
  const capture::SourceInfo& info = source->info();
  const Intrinsics& in = info.intrinsics;
  row("file", path.string());
  row("type", "recording (7-Scenes folder)");
  row("frames", fmt("%zu", info.frame_count.value_or(0)));
  row("intrinsics",
      fmt("fx %.1f fy %.1f cx %.1f cy %.1f, %dx%d px (%s%s)", in.fx_px, in.fy_px, in.cx_px,
          in.cy_px, in.width_px, in.height_px, info.intrinsics_assumed ? "ASSUMED: " : "",
          info.intrinsics_origin.c_str()));
  row("depth units", info.depth_units);
  row("ground truth", info.ground_truth
                          ? fmt("%zu poses (frame-*.pose.txt), %.3f m path",
                                info.ground_truth->size(), info.ground_truth->pathLengthM())
                          : std::string("none"));
}

static void describeOni(const fs::path& path) {
  const capture::OniFileSummary summary = capture::inspectOniFile(path);  // throws when broken
  row("recording", "OpenNI2 .oni, " + bytesText(summary.bytes));
  std::string streams = capture::describe(summary);
  std::size_t start = 0;
  while (start < streams.size()) {
    const std::size_t end = streams.find('\n', start);
    row("stream", streams.substr(start, end - start));
    start = end == std::string::npos ? streams.size() : end + 1;
  }
  const std::unique_ptr<capture::FrameSource> source = capture::openOniFile(path);
  const capture::SourceInfo& info = source->info();
  const Intrinsics& in = info.intrinsics;
  row("intrinsics", fmt("fx %.2f fy %.2f cx %.2f cy %.2f, %dx%d (%s)", in.fx_px, in.fy_px, in.cx_px,
                        in.cy_px, in.width_px, in.height_px, info.intrinsics_origin.c_str()));
  row("frames", fmt("%zu", info.frame_count.value_or(0)));
  row("ground truth",
      info.ground_truth ? fmt("%zu poses (%s)", info.ground_truth->size(),
                              capture::RecordingSidecars::of(path).ground_truth.filename().c_str())
                        : std::string("none"));
}

void runInfo(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found)
    throw InputError(path, "no such file or directory");
  if (ec) throw InputError(path, "cannot access: " + ec.message());
  if (status.type() == fs::file_type::directory) {
    if (fs::exists(path / report::kHypothesesFile, ec)) {
      describeResults(path);
      return;
    }
    if (capture::SevenScenesFolder::looksLikeSevenScenesFolder(path)) {
      describeSevenScenesFolder(path);
      return;
    }
    if (!capture::TumFolder::looksLikeTumFolder(path)) {
      throw InputError(path,
                       "is a directory, not a results folder (hypotheses.json), a TUM-format or a "
                       "7-Scenes recording (a recording folder has depth.txt or associations.txt, "
                       "or frame-NNNNNN.depth.png files)");
    }
    describeTumFolder(path);
    return;
  }
  if (status.type() != fs::file_type::regular) throw InputError(path, "is not a regular file");
  if (fs::file_size(path, ec) == 0) throw InputError(path, "the file is empty");

  const std::string ext = lowercaseExtension(path);
  if (startsWith(path, "ply") || ext == ".ply") {
    describeMesh(path);
  } else if (ext == ".oni") {
    describeOni(path);
  } else if (ext == ".txt") {
    describeTrajectory(path);
  } else if (ext == ".pcd") {
    describePcd(path);
  } else if (ext == ".obj" || ext == ".stl" || ext == ".glb") {
    describeMeshFile(path);
  } else if (startsWith(path, std::string_view("SQLite format 3\0", 16))) {
    describeCatalog(path);
  } else if (path.filename() == report::kHypothesesFile) {
    describeResults(path.parent_path().empty() ? fs::path(".") : path.parent_path());
  } else if (ext == ".json" || startsWith(path, "{")) {
    describeModel(path);  // JSON, whatever its name (objscan train --model m.yml writes JSON)
  } else {
    throw InputError(path,
                     "unknown format: expected a .ply, .pcd, .obj, .stl or .glb mesh, a .txt TUM "
                     "trajectory, a .oni recording, a catalog (SQLite), a model (.json), a results "
                     "folder or a TUM-format or 7-Scenes recording folder");
  }
}

}  // namespace objscan::app
