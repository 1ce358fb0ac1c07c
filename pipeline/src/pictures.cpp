#include "objscan/pipeline/pictures.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include "objscan/core/clock.h"
#include "objscan/core/error.h"
#include "objscan/core/image_codec.h"
#include "objscan/core/memory.h"
#include "objscan/core/progress.h"

namespace objscan::pipeline {
namespace {

/// OSMesa's llvmpipe crashes (SIGSEGV) when it runs out of memory, so the pictures are refused
/// first when they will not fit: on the 237 k-vertex TUM desk at 1280x960, `objscan render`
/// grew from a VmSize of about 380 MB at this point to 1.13 GB (llvmpipe's threads and JIT, the
/// GL copies of the mesh, the frame buffers), and under `ulimit -v` it crashed below 800 MB and
/// ran at 1.2 GB: so 600 MB, 150 bytes per vertex and 40 bytes per overview pixel. Measured on
/// one mesh, not a guarantee.
void requireMemoryForPictures(const TriangleMesh& mesh, const PictureOptions& options) {
  const std::optional<std::uint64_t> available = availableMemoryBytes();
  if (!available) return;
  const double needed = 600e6 + 150.0 * static_cast<double>(mesh.positions.size()) +
                        40.0 * options.width * options.height;
  if (needed <= static_cast<double>(*available)) return;
  throw std::runtime_error("the pictures of a mesh of " + std::to_string(mesh.positions.size()) +
                           " vertices need about " + bytesText(static_cast<std::uint64_t>(needed)) +
                           ", more than " + availableMemoryText(*available) +
                           " (a smaller --size needs a little less; render where more memory "
                           "is free)");
}

report::Picture pngPicture(const cv::Mat& image) {
  report::Picture p;
  p.png = encodePng(image);
  p.width = static_cast<std::uint32_t>(image.cols);
  p.height = static_cast<std::uint32_t>(image.rows);
  return p;
}

std::vector<render::PaintedHypothesis> painted(
    const TriangleMesh& mesh, const std::vector<report::HypothesisRecord>& hypotheses,
    std::size_t top, const std::string& what) {
  std::vector<render::PaintedHypothesis> out;
  for (const report::HypothesisRecord& h : hypotheses) {
    if (out.size() == top) break;
    if (h.vertices.empty()) {
      throw InputError(what, "hypothesis " + std::to_string(h.rank) + " has no vertices");
    }
    for (std::int32_t v : h.vertices) {
      if (v < 0 || static_cast<std::size_t>(v) >= mesh.positions.size()) {
        throw InputError(what, "hypothesis " + std::to_string(h.rank) + " names vertex " +
                                   std::to_string(v) + ", but its scene has " +
                                   std::to_string(mesh.positions.size()) + " vertices");
      }
    }
    // Objects are ranked by their object score: the caption shows the number they are ranked by.
    if (const std::optional<double> object_score = h.objectScoreIfObject()) {
      out.push_back({h.rank, *object_score, h.vertices, true});
    } else {
      out.push_back({h.rank, h.score.value_or(NAN), h.vertices});
    }
  }
  return out;
}

}  // namespace

void PictureOptions::validate() const {
  if (top == 0) throw std::invalid_argument("--top must be at least 1");
  if (width < 64 || height < 48 || width > 8192 || height > 8192) {
    throw std::invalid_argument("--size must lie between 64x48 and 8192x8192");
  }
}

PicturesOutcome renderPictures(const TriangleMesh& mesh, const Trajectory* trajectory,
                               const std::vector<report::HypothesisRecord>& hypotheses,
                               const PictureOptions& options, const std::string& what) {
  const auto start = SteadyClock::now();
  options.validate();
  requireMemoryForPictures(mesh, options);
  const auto stopped = [&options] { return options.stop && options.stop->load(); };
  PicturesOutcome out;
  std::vector<render::PaintedHypothesis> paint = painted(mesh, hypotheses, options.top, what);
  out.painted = paint.size();
  report::Pictures& pictures = out.pictures;
  // The overview, each close-up, and the contact sheet when there is a close-up to put on it.
  ProgressBar progress(options.progress_label, 1 + out.painted + (out.painted > 0 ? 1 : 0));
  render::SnapshotRenderer renderer(mesh, paint);
  const render::SnapshotView view =
      render::overviewView(mesh, trajectory, paint, options.width, options.height, options.view);
  out.view = view.kind;
  pictures.camera =
      report::OverviewCamera{render::toString(view.kind), view.T_W_C, view.intrinsics};
  const render::Snapshot overview = renderer.overview(view);
  pictures.overview = pngPicture(overview.bgr);
  pictures.visible = overview.labelled;
  ++out.images;
  if (options.ranks_image) {
    cv::Mat ranks16;
    overview.ranks.convertTo(ranks16, CV_16U);
    pictures.overview_ranks = pngPicture(ranks16);
    ++out.images;
  }
  progress.advance();
  const int w = std::max(160, options.width * 3 / 8), h = std::max(120, options.height * 3 / 8);
  std::vector<cv::Mat> closeups;
  for (std::size_t i = 0; i < paint.size() && !stopped(); ++i) {
    closeups.push_back(renderer.closeUp(i, view, w, h).bgr);
    pictures.closeups[paint[i].rank] = pngPicture(closeups.back());
    ++out.images;
    progress.advance();
  }
  if (stopped()) {
    out.interrupted = true;
  } else if (!closeups.empty()) {
    pictures.contact_sheet = pngPicture(render::contactSheet(closeups, paint));
    ++out.images;
    progress.advance();
  }
  out.seconds = secondsSince(start);
  return out;
}

}  // namespace objscan::pipeline
