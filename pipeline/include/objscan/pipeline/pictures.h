#pragma once

#include <atomic>
#include <cstddef>
#include <string>
#include <vector>

#include "objscan/core/trajectory.h"
#include "objscan/core/triangle_mesh.h"
#include "objscan/render/snapshots.h"
#include "objscan/report/results.h"

/// The pictures stage: the overview with the top hypotheses painted, a close-up of each, and the
/// contact sheet, rendered off-screen (OSMesa) and encoded as PNG in memory.
namespace objscan::pipeline {

struct PictureOptions {
  std::size_t top = report::kDefaultPaintedTop;  ///< hypotheses painted and shown in close-up
  int width = 1280, height = 960;  ///< the overview; close-ups are 3/8 of it on each side
  render::ViewKind view = render::ViewKind::kAuto;
  /// Also the 16-bit rank image (overview_ranks.png): each pixel the rank painted there (0: none),
  /// so that scripts and tests can check what the overview shows.
  bool ranks_image = false;
  std::string progress_label = "rendering pictures";
  /// Polled between pictures: set, the pictures stop (PicturesOutcome::interrupted).
  const std::atomic<bool>* stop = nullptr;

  /// Throws std::invalid_argument naming the bad option.
  void validate() const;
};

struct PicturesOutcome {
  report::Pictures pictures;
  render::ViewKind view = render::ViewKind::kAuto;  ///< the kind of overview camera used
  std::size_t painted = 0;                          ///< hypotheses painted (min(top, given))
  std::size_t images = 0;                           ///< PNG pictures made
  double seconds = 0.0;
  bool interrupted = false;  ///< stopped before the last picture: the pictures are incomplete
};

/// Renders the pictures of the best `options.top` of `hypotheses` (records of `mesh`'s scene, best
/// first) over `mesh`, from `trajectory`'s viewpoint when there is one. Throws InputError naming
/// `what` (the file the hypotheses came from) for a hypothesis naming a vertex the mesh lacks.
PicturesOutcome renderPictures(const TriangleMesh& mesh, const Trajectory* trajectory,
                               const std::vector<report::HypothesisRecord>& hypotheses,
                               const PictureOptions& options, const std::string& what);

}  // namespace objscan::pipeline
