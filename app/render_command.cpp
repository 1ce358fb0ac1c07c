#include "render_command.h"

#include <chrono>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "exit_codes.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/progress.h"
#include "objscan/core/trajectory.h"
#include "output_folder.h"
#include "report.h"
#include "stop_signals.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// What render needs from hypotheses.json: the scene mesh it was made from and the hypotheses of
/// that scene, best first.
struct RankedResults {
  fs::path mesh;
  std::size_t mesh_vertices = 0;
  std::size_t scenes = 0;
  std::vector<render::PaintedHypothesis> hypotheses;
};

RankedResults readRankedResults(const fs::path& dir) {
  const fs::path file = dir / "hypotheses.json";
  if (!fs::exists(file)) {
    throw InputError(file, "missing: not a results folder of objscan scan or discover");
  }
  RankedResults out;
  try {
    const nlohmann::json doc = nlohmann::json::parse(readWholeFile(file));
    const nlohmann::json& scenes = doc.at("scenes");
    if (scenes.empty()) throw InputError(file, "lists no scene");
    out.scenes = scenes.size();
    const std::string scene = scenes.at(0).at("mesh").get<std::string>();
    out.mesh_vertices = scenes.at(0).at("vertices").get<std::size_t>();
    // The results folder's own mesh first (scan writes it there), else the path discover noted,
    // as given or relative to the folder.
    out.mesh = dir / "mesh.ply";
    if (!fs::exists(out.mesh)) {
      out.mesh = scene;
      if (!fs::exists(out.mesh) && fs::path(scene).is_relative()) out.mesh = dir / scene;
    }
    for (const nlohmann::json& h : doc.at("hypotheses")) {
      if (h.at("scene").get<std::string>() != scene) continue;
      render::PaintedHypothesis p;
      p.rank = h.at("rank").get<std::size_t>();
      p.score = h.at("score").get<double>();
      p.vertices = h.at("vertices").get<std::vector<std::int32_t>>();
      if (p.rank == 0 || p.vertices.empty()) {
        throw InputError(file, "hypothesis " + std::to_string(p.rank) + " has " +
                                   (p.rank == 0 ? "rank 0" : "no vertices"));
      }
      for (std::int32_t v : p.vertices) {
        if (v < 0 || static_cast<std::size_t>(v) >= out.mesh_vertices) {
          throw InputError(file, "hypothesis " + std::to_string(p.rank) + " names vertex " +
                                     std::to_string(v) + ", but its scene has " +
                                     std::to_string(out.mesh_vertices) + " vertices");
        }
      }
      out.hypotheses.push_back(std::move(p));
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(file, std::string("not the JSON objscan writes: ") + e.what());
  }
  if (!fs::exists(out.mesh)) {
    throw InputError(dir / "mesh.ply",
                     "missing: render needs the scene mesh hypotheses.json was made from (mesh.ply "
                     "in the results folder, or " +
                         out.mesh.string() + ")");
  }
  return out;
}

void writePng(const fs::path& path, const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  if (!cv::imencode(".png", image, bytes)) throw OutputError(path, "could not encode the PNG");
  writeFileAtomically(path,
                      std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

/// The overview's camera, so that a script can project into (or render again) the same picture:
/// T_W_C row by row (camera x right, y down, z forward, metres) and pinhole intrinsics.
nlohmann::json cameraJson(const render::SnapshotView& view) {
  nlohmann::json rows = nlohmann::json::array();
  const Eigen::Matrix4f T = view.T_W_C.matrix();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  const Intrinsics& in = view.intrinsics;
  return {{"view", render::toString(view.kind)},
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

RenderOutcome renderResults(const RenderCommandOptions& options) {
  const auto start = Clock::now();
  if (options.top == 0) throw std::invalid_argument("--top must be at least 1");
  if (options.width < 64 || options.height < 48 || options.width > 8192 || options.height > 8192) {
    throw std::invalid_argument("--size must lie between 64x48 and 8192x8192");
  }
  if (!fs::is_directory(options.dir)) {
    throw InputError(options.dir, fs::exists(options.dir) ? "not a folder" : "missing");
  }
  RankedResults results = readRankedResults(options.dir);
  if (results.scenes > 1) {
    log::warning("hypotheses.json holds " + std::to_string(results.scenes) +
                 " scenes; rendering the first, " + results.mesh.string());
  }
  const TriangleMesh mesh = readPly(results.mesh);
  if (mesh.positions.size() != results.mesh_vertices) {
    throw InputError(results.mesh, "has " + std::to_string(mesh.positions.size()) +
                                       " vertices, but hypotheses.json was made from a mesh of " +
                                       std::to_string(results.mesh_vertices) +
                                       " (run discover again)");
  }
  std::optional<Trajectory> trajectory;
  if (fs::exists(options.dir / "trajectory.txt")) {
    trajectory = readTumTrajectory(options.dir / "trajectory.txt");
  }
  if (results.hypotheses.size() > options.top) results.hypotheses.resize(options.top);

  RenderOutcome out;
  out.renders = options.dir / "renders";
  out.painted = results.hypotheses.size();
  const fs::path partial = freshPartialFolder(options.dir, "renders");
  // Whatever stops the pictures (an error, Ctrl-C), the staging folder goes: renders/ stays as
  // it was.
  struct RemoveUnlessSwapped {
    fs::path path;
    bool swapped = false;
    ~RemoveUnlessSwapped() {
      std::error_code ec;
      if (!swapped) fs::remove_all(path, ec);
    }
  } staging{partial};
  {
    ProgressBar progress(options.progress_label, out.painted + 2);
    render::SnapshotRenderer renderer(mesh, results.hypotheses);
    const render::SnapshotView view =
        render::overviewView(mesh, trajectory ? &*trajectory : nullptr, results.hypotheses,
                             options.width, options.height, options.view);
    out.view = view.kind;
    writeFileAtomically(partial / "overview_camera.json", cameraJson(view).dump(1) + "\n");
    const render::Snapshot overview = renderer.overview(view);
    writePng(partial / "overview.png", overview.bgr);
    out.visible = overview.labelled;
    ++out.images;
    if (options.ranks_image) {
      cv::Mat ranks16;
      overview.ranks.convertTo(ranks16, CV_16U);
      writePng(partial / "overview_ranks.png", ranks16);
      ++out.images;
    }
    progress.advance();
    const int w = std::max(160, options.width * 3 / 8), h = std::max(120, options.height * 3 / 8);
    std::vector<cv::Mat> closeups;
    for (std::size_t i = 0; i < results.hypotheses.size(); ++i) {
      if (StopSignals::stopRequested()) break;
      closeups.push_back(renderer.closeUp(i, view, w, h).bgr);
      writePng(partial / rankFileName(results.hypotheses[i].rank, ".png"), closeups.back());
      ++out.images;
      progress.advance();
    }
    if (StopSignals::stopRequested()) {
      out.interrupted = true;
    } else if (!closeups.empty()) {
      writePng(partial / "contact_sheet.png", render::contactSheet(closeups, results.hypotheses));
      ++out.images;
      progress.advance();
    }
  }
  if (!out.interrupted) {
    swapInFolder(options.dir, "renders");
    staging.swapped = true;
  }
  out.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return out;
}

int runRender(const RenderCommandOptions& options) {
  RenderOutcome outcome;
  {
    StopSignals signals;
    outcome = renderResults(options);
  }
  if (outcome.interrupted) {
    std::printf("stopped by    Ctrl-C / SIGTERM: %s was left as it was\n",
                outcome.renders.string().c_str());
    return kExitInterrupted;
  }
  std::string visible;
  for (std::size_t rank : outcome.visible)
    visible += (visible.empty() ? "#" : ", #") + std::to_string(rank);
  std::printf("painted       top %zu hypotheses; visible in the overview: %s\n", outcome.painted,
              visible.empty() ? "none" : visible.c_str());
  std::printf("view          %s\n", render::toString(outcome.view));
  std::printf("written       %zu pictures -> %s in %.1f s\n", outcome.images,
              outcome.renders.string().c_str(), outcome.seconds);
  std::printf("report        %s\n", writeReport(options.dir).string().c_str());
  return kExitSuccess;
}

}  // namespace objscan::app
