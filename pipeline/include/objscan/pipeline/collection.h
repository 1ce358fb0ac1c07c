#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

/// A batch's collection page (DIR/index.html): each scene with its best objects in the
/// collection's ranking, and objects across scenes, with their pictures rendered off-screen.
namespace objscan::pipeline {

/// A recording of the batch: its results in DIR/<name>/.
struct CollectionRecording {
  std::string name, source;
};

struct CollectionPageOptions {
  std::size_t objects_per_scene = 5;  ///< each scene's best objects shown
  /// Objects across scenes: the collection's best objects (at most this many, best first), each
  /// with the segments of other scenes nearest to it.
  std::size_t groups = 8;
  int neighbours = 10;    ///< the paper's k
  int picture_size = 168;  ///< close-ups are picture_size x picture_size
  std::string viewer_url = "http://127.0.0.1:8090/";
};

struct CollectionPageOutcome {
  std::filesystem::path page;
  std::size_t scenes = 0, groups = 0, pictures = 0, pictures_failed = 0;
  double seconds = 0.0;
};

/// Writes `dir`/index.html and its pictures (`dir`/collection/pictures/, made afresh) from
/// `dir`/collection/hypotheses.json (the collection ranked by `objscan discover`) and the catalog
/// it names (objects across scenes need one: without, the page says so). `recordings` are the
/// batch's, in its order; those with complete results are the scenes of the collection, the
/// others are counted as failed. A picture that cannot be rendered is left out (the page says "no
/// picture") and counted. Throws InputError when the collection's results cannot be read,
/// OutputError when the page cannot be written.
CollectionPageOutcome writeCollectionPage(const std::filesystem::path& dir,
                                          const std::vector<CollectionRecording>& recordings,
                                          const CollectionPageOptions& options = {});

}  // namespace objscan::pipeline
