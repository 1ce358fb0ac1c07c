#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
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
  /// contentHash() of the mesh file, then " up X Y Z" for a scene whose candidates depend on
  /// the camera's up (discoverScenes' catalog key)
  std::string content_hash;
  std::size_t vertex_count = 0;
  /// A key of the discovery settings the segments were made with: a scene is found again only
  /// with the same hash and the same settings, so changing a setting means recomputing.
  std::string settings;
};

/// A person's judgement of a segment (objscan view): stored as 1, 0 and 2.
enum class SegmentLabel { kNotObject = 0, kObject = 1, kUnsure = 2 };

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
  /// SegmentLabel's values: 1 object, 0 not an object, 2 unsure; nothing when unlabelled.
  std::optional<int> label;
  /// Who set the label and when (ISO 8601 UTC, e.g. "2026-11-25T14:51:46.123Z"); empty when
  /// unlabelled. addScene stores `labelled_by` (or "objscan" when empty) and the time it runs.
  std::string labelled_by, labelled_at;
  std::vector<std::int32_t> vertices;  ///< indices into the scene mesh
};

/// One change of a segment's label, as the catalog's history keeps it.
struct LabelEvent {
  std::int64_t id = 0;  ///< increasing; never reused
  std::int64_t segment_id = 0, scene_id = 0;
  std::optional<int> label;            ///< 0, 1, 2; nothing: the label was cleared
  std::optional<int> previous;         ///< the label before; nothing: it had none
  std::string by, at;                  ///< who, and when (ISO 8601 UTC)
  std::optional<std::int64_t> undoes;  ///< the event this one undid
  /// Who made the previous label, and when (empty when it had none): an undo puts it back with
  /// them, so the label is never credited to the person who undid.
  std::string previous_by, previous_at;
};

/// How many of a scene's segments carry each label.
struct LabelCounts {
  std::size_t segments = 0, labelled = 0, objects = 0, not_objects = 0, unsure = 0;
};

/// Thrown by undoLabel when the segment's label has changed since the event (another tab or
/// person).
class LabelConflict : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Why `name` cannot name who set a label, or empty when it can: a name is 1 to 64 characters of
/// UTF-8 with at least one visible one; no control character (C0, DEL, C1: terminal escapes
/// included), line or paragraph separator, text-direction mark, embedding, override or isolate,
/// byte order mark, or other invisible format character (a name of only invisible spaces has no
/// visible one). The text never quotes the name (it may hold what a terminal obeys).
std::string labellerNameProblem(std::string_view name);

/// An SQLite catalog file. Numbers round-trip exactly (floats and doubles bit for bit, NaN as
/// NaN; only -0 reads back as +0, as SQLite's REAL columns store it). Every write is one
/// transaction, so a crash or an error leaves the file as it was before the call. One Catalog must
/// not be used from several threads at once (a caller serialises them, e.g. with a mutex); several
/// Catalogs, in one process or several, may open the same file: each write takes the file's write
/// lock up front (BEGIN IMMEDIATE) and a writer waits up to 10 s for another's transaction, so no
/// write is lost or half done.
///
/// People's labels live beside the segments with who set them and when, and every change is an
/// event in a history that is only ever appended to (an undo is a new event).
class Catalog {
 public:
  /// 2: people's labels (0, 1, 2) with who and when, and their history. A file of version 1 is
  /// upgraded when opened (its labels kept, by "objscan (schema 1)").
  static constexpr int kSchemaVersion = 2;

  /// Opens the catalog at `path`, or creates it (and its tables) when nothing is there: made whole
  /// under a temporary name and linked into place, so that no other process (and no later run,
  /// after a kill) ever finds a half-made catalog. The folder must exist. The whole file is checked
  /// (SQLite's PRAGMA quick_check) before anything is written or read. A catalog of schema
  /// version 1 is upgraded to 2 in one transaction (all or nothing).
  /// Throws objscan::InputError naming the file, which is then left as it was, when it is a
  /// folder, not a regular file (a device such as /dev/null, a FIFO), empty (0 bytes: not a
  /// catalog, and not made one), not an SQLite database, damaged (quick_check fails), an SQLite
  /// database without objscan's tables, or a catalog of a newer schema version;
  /// objscan::OutputError when it cannot be created (e.g. the folder is missing) or a version-1
  /// file cannot be upgraded (read-only, locked too long, disk full).
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
  /// and scene ids are ignored; a segment's label is stored with its `labelled_by` (or "objscan")
  /// and the time now, and recorded as an event. Throws std::invalid_argument for data the
  /// catalog refuses (a negative scale or extent, a label other than 0, 1 or 2; a replaced
  /// scene's labels and their history go with its segments), objscan::OutputError when the write
  /// fails (disk full, read-only file, locked too long); the catalog is then unchanged.
  std::int64_t addScene(const CatalogScene& scene, const std::vector<CatalogSegment>& segments);

  /// Every scene, in the order they were added.
  std::vector<CatalogScene> scenes() const;

  /// The scenes with this content hash (any settings, and any camera's up: discoverScenes keys
  /// a scene seen with one as "<hash> up X Y Z"), in the order added.
  std::vector<CatalogScene> scenesWithHash(const std::string& content_hash) const;

  /// The scene's segments in the order they were added (empty for an unknown scene); their
  /// vertex lists only when `with_vertices`.
  std::vector<CatalogSegment> segments(std::int64_t scene_id, bool with_vertices) const;

  /// Sets the labels (1 object, 0 not, 2 unsure) of some of a scene's segments, given by segment
  /// id, by `by`, now, each recorded as an event, in one transaction. Throws
  /// std::invalid_argument, changing nothing, for a label other than 0, 1 or 2, a segment that is
  /// not in the scene or a `by` that labellerNameProblem refuses.
  void setLabels(std::int64_t scene_id,
                 const std::vector<std::pair<std::int64_t, int>>& segment_labels,
                 const std::string& by = "objscan");

  /// Sets (or with nothing, clears) one segment's label, by `by`, now, and records the event, in
  /// one transaction. Throws std::invalid_argument for an unknown segment, a label not 0/1/2 or a
  /// `by` that labellerNameProblem refuses (nothing changed), OutputError when the write fails.
  /// Setting the label a segment already has is recorded too.
  LabelEvent setLabel(std::int64_t segment_id, std::optional<int> label, const std::string& by);

  /// Undoes event `event_id`: puts the segment's label back to the event's `previous`, recorded as
  /// a new event (undoes = event_id), in one transaction; throws LabelConflict (nothing changed)
  /// when the event is no longer the segment's latest (somebody changed the label since, or the
  /// event was already undone), std::invalid_argument for an unknown event or a `by` that
  /// labellerNameProblem refuses.
  /// Undoing an undo puts the undone label back.
  LabelEvent undoLabel(std::int64_t event_id, const std::string& by);

  /// How many of the scene's segments carry each label (all 0 for an unknown scene).
  LabelCounts labelCounts(std::int64_t scene_id) const;

  /// The scene's label events, oldest first.
  std::vector<LabelEvent> labelEvents(std::int64_t scene_id) const;

  /// Every segment of every scene as recurrence needs it (no vertices), in one query.
  std::vector<RecurrenceEntry> recurrenceEntries() const;

  /// The number of segments of all scenes.
  std::size_t segmentCount() const;

  /// False when SQLite could open the file for reading only (the file is write-protected): every
  /// write would then fail. (A folder that forbids SQLite's journal is only found by writing.)
  bool writable() const;

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

/// Adds to `into` every scene of `from` that `into` does not hold with the same content hash and
/// settings, with its segments, their vertices and their current labels (by whoever set them;
/// the label history stays in `from`). Returns how many scenes were added. Each scene is one
/// transaction, and a scene already there is left alone: merging the same catalog again changes
/// nothing, and a merge cut short is finished by running it again. `objscan batch` builds its
/// collection's catalog so from the catalogs of its scans, which no two processes ever write.
/// `take`, when given, chooses which of `from`'s scenes are merged.
std::size_t mergeCatalog(Catalog& into, const Catalog& from,
                         const std::function<bool(const CatalogScene&)>& take = {});

}  // namespace objscan::discovery
