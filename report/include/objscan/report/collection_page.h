#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

/// DIR/index.html of `objscan batch`: the collection of scenes, each with its best objects, and
/// objects across scenes (the paper's Fig. 6: a segment and the segments of other scenes most
/// like it). Written from values; the pictures are files beside it, linked relatively.
namespace objscan::report {

/// A segment the page shows: a ranked hypothesis of the collection, or a catalog segment.
struct CollectionItem {
  std::string scene;             ///< the recording's name (DIR/<scene>/)
  std::size_t scene_index = 0;   ///< its place among the collection's scenes (the viewer's scene)
  std::optional<std::size_t> rank;       ///< its rank in the collection, when it is a hypothesis
  std::optional<std::int64_t> segment;   ///< its id in the collection's catalog
  std::optional<double> score;           ///< the score it is ranked by
  std::optional<double> distance;        ///< to the group's query, z-normalised measure units
  Eigen::Vector3f extents = Eigen::Vector3f::Zero();  ///< metres, decreasing
  std::string picture;  ///< relative to the page's folder; empty when it could not be rendered
};

struct CollectionSceneEntry {
  std::string name, source;
  std::string report;  ///< its report.html relative to the page's folder; empty when missing
  std::size_t hypotheses = 0;
  std::vector<CollectionItem> objects;  ///< its best objects in the collection's ranking
};

/// A query segment and the segments of other scenes nearest to it.
struct CollectionGroup {
  CollectionItem query;
  std::vector<CollectionItem> neighbours;  ///< nearest first
};

struct CollectionPage {
  std::string title;         ///< the batch folder, as given
  std::string viewer_url;    ///< where `view_command` serves the viewer, e.g. http://127.0.0.1:8090/
  std::string view_command;  ///< the command that serves the collection in the viewer
  std::vector<CollectionSceneEntry> scenes;
  std::vector<CollectionGroup> groups;
  /// Why there are no groups (no catalog, no scene with another to compare with); empty when
  /// there are.
  std::string groups_missing;
  std::size_t failed = 0;  ///< recordings of the batch without complete results (not shown)
};

/// Writes `file` (atomically) and returns it. Links to the viewer are the viewer URL with
/// `#scene=I&rank=N` or `#scene=I&segment=ID`. The body carries data-scenes, data-groups and,
/// once loaded, data-images="<decoded>/<total>" and data-errors (report.html's check). Throws
/// OutputError when it cannot be written.
std::filesystem::path writeCollectionPage(const CollectionPage& page,
                                          const std::filesystem::path& file);

}  // namespace objscan::report
