#pragma once

#include <filesystem>

#include "objscan/pipeline/pictures.h"
#include "objscan/report/results.h"

namespace objscan::app {

struct RenderCommandOptions {
  std::filesystem::path dir;  ///< a results folder: hypotheses.json, mesh.ply, trajectory.txt
  pipeline::PictureOptions pictures;
  report::Settings settings;  ///< render's command line: its picture options go into the folder's
};

/// Prints the pictures line of render and scan.
void printPictures(const char* label, const pipeline::PicturesOutcome& outcome,
                   const std::filesystem::path& dir);

/// `objscan render DIR`: reads the folder's results, renders DIR/renders/ and writes
/// DIR/report.html again. Returns the exit code.
int runRender(const RenderCommandOptions& options);

}  // namespace objscan::app
