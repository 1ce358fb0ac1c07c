#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "objscan/discovery/recurrence.h"
#include "objscan/discovery/shape_measures.h"

/// The catalog: every segment of every scene processed so far, in one SQLite file, so that scenes
/// can be processed one at a time, in any order, without recomputing any (the paper processes
/// scenes "online one by one and in no particular order"), and recurrence can compare a scene's
/// segments with all the others.
namespace objscan::discovery {

/// One scene as the catalog knows it.
struct CatalogScene {
  std::int64_t id = 0;       ///< assigned by the catalog; never reused
  std::string name;          ///< for people: e.g. the mesh file's name
  std::string content_hash;  ///< contentHash() of the mesh file
  std::size_t vertex_count = 0;
  /// A key of the discovery settings the segments were made with: a scene is found again only
  /// with the same hash and the same settings, so changing a setting means recomputing.
  std::string settings;
};

/// One segment of a scene: Segment's statistics, its measures and its label.
struct CatalogSegment {
  std::int64_t id = 0;        ///< assigned by the catalog; never reused; ignored by addScene
  std::int64_t scene_id = 0;  ///< ignored by addScene
  float scale = 0.0f;         ///< the segmentation granularity; the catalog rejects a negative one
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();  ///< principal axes (columns)
  Eigen::Vector3f eigenvalues = Eigen::Vector3f::Zero();
  Eigen::Vector3f extents = Eigen::Vector3f::Zero();  ///< metres; the catalog rejects negatives
  /// The five shape measures. Recurrence is not stored (it depends on the rest of the catalog):
  /// it reads back as NaN, like any measure stored as NaN.
  ShapeMeasures measures;
  std::optional<int> label;            ///< 1 object, 0 not an object, nothing when unknown
  std::vector<std::int32_t> vertices;  ///< indices into the scene mesh
};

/// An SQLite catalog file. Numbers round-trip exactly (floats and doubles bit for bit, NaN as
/// NaN; only -0 reads back as +0, as SQLite's REAL columns store it). Every write is one
/// transaction, so a crash or an error leaves the file as it was before the call. One Catalog must
/// not be used from several threads at once; several processes may open the same file (a writer
/// waits up to 10 s for another's transaction).
class Catalog {
 public:
  static constexpr int kSchemaVersion = 1;

  /// Opens the catalog at `path`, or creates it (and its tables) when the file does not exist or
  /// is empty (0 bytes: SQLite's own reading of an empty file). The folder must exist.
  /// Throws objscan::InputError naming the file when it is a folder, not an SQLite database or
  /// damaged, an SQLite database without objscan's tables, or a catalog of a newer schema
  /// version; objscan::OutputError when it cannot be created (e.g. the folder is missing).
  explicit Catalog(const std::filesystem::path& path);
  ~Catalog();
  /// A moved-from catalog may only be assigned to or destroyed.
  Catalog(Catalog&&) noexcept;
  Catalog& operator=(Catalog&&) noexcept;
  Catalog(const Catalog&) = delete;
  Catalog& operator=(const Catalog&) = delete;

  /// The scene with this content hash and settings, if the catalog has it.
  std::optional<CatalogScene> findScene(const std::string& content_hash,
                                        const std::string& settings) const;

  /// Adds a scene and its segments in one transaction and returns the scene's new id (its
  /// segments' ids are found through segments()). A scene of the same hash and settings is
  /// replaced, its segments deleted, in the same transaction. `scene.id` and the segments' ids
  /// and scene ids are ignored. Throws std::invalid_argument for data the catalog refuses (a
  /// negative scale or extent, a label other than 0 or 1), objscan::OutputError when the write
  /// fails (disk full, read-only file, locked too long); the catalog is then unchanged.
  std::int64_t addScene(const CatalogScene& scene, const std::vector<CatalogSegment>& segments);

  /// Every scene, in the order they were added.
  std::vector<CatalogScene> scenes() const;

  /// The scene's segments in the order they were added (empty for an unknown scene); their
  /// vertex lists only when `with_vertices`.
  std::vector<CatalogSegment> segments(std::int64_t scene_id, bool with_vertices) const;

  /// Sets the labels (1 object, 0 not) of some of a scene's segments, given by segment id, in one
  /// transaction. Throws std::invalid_argument, changing nothing, for a label other than 0 or 1
  /// or a segment that is not in the scene.
  void setLabels(std::int64_t scene_id,
                 const std::vector<std::pair<std::int64_t, int>>& segment_labels);

  /// Every segment of every scene as recurrence needs it (no vertices), in one query.
  std::vector<RecurrenceEntry> recurrenceEntries() const;

  /// The number of segments of all scenes.
  std::size_t segmentCount() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A 64-bit FNV-1a hash of the file's bytes as 16 lowercase hex digits: identifies a mesh file's
/// content, so that a scene already in the catalog is not recomputed. Not cryptographic. Stored in
/// catalogs, so it must never change. Throws objscan::InputError when the file cannot be read.
std::string contentHash(const std::filesystem::path& file);
/// The same hash of bytes in memory: contentHashOfBytes(a file's bytes) == contentHash(the file).
std::string contentHashOfBytes(std::string_view bytes);

}  // namespace objscan::discovery
