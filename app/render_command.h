#pragma once

#include <cstddef>
#include <filesystem>
#include <vector>

#include "objscan/render/snapshots.h"

namespace objscan::app {

struct RenderCommandOptions {
  std::filesystem::path dir;       ///< a results folder: hypotheses.json, mesh.ply, trajectory.txt
  std::size_t top = 5;             ///< hypotheses painted and shown in close-up
  int width = 1280, height = 960;  ///< the overview; close-ups are 3/8 of it on each side
  render::ViewKind view = render::ViewKind::kAuto;
  /// Also write renders/overview_ranks.png: 16-bit, each pixel the rank painted there (0: none),
  /// so that scripts and tests can check what the overview shows.
  bool ranks_image = false;
  std::string progress_label = "rendering pictures";
};

/// What a render run wrote.
struct RenderOutcome {
  std::filesystem::path renders;                    ///< DIR/renders
  std::size_t painted = 0;                          ///< hypotheses painted (min(top, hypotheses))
  std::vector<std::size_t> visible;                 ///< ranks labelled in the overview
  render::ViewKind view = render::ViewKind::kAuto;  ///< the kind of overview camera used
  std::size_t images = 0;
  double seconds = 0.0;
  bool interrupted = false;  ///< stopped by Ctrl-C: nothing was moved into DIR/renders
};

/// Renders DIR/renders/: overview.png, overview_camera.json (its camera, intrinsics.json's keys
/// under "intrinsics"), rank_NNN.png (a close-up per painted hypothesis) and contact_sheet.png,
/// into a fresh folder swapped in at the end. Reads DIR/hypotheses.json, the scene mesh
/// (DIR/mesh.ply, else the mesh hypotheses.json names) and DIR/trajectory.txt when it exists. Polls
/// StopSignals between pictures (the caller installs them). Throws InputError naming the missing or
/// unusable file, OutputError when DIR cannot be written.
RenderOutcome renderResults(const RenderCommandOptions& options);

/// `objscan render DIR`: renderResults, then DIR/report.html again. Returns the exit code.
int runRender(const RenderCommandOptions& options);

}  // namespace objscan::app
