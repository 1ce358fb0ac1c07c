#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "objscan/discovery/shape_measures.h"

/// The paper's recurrence measure (section IV-B, "Recurrence"): segments that resemble segments
/// of other scenes, in size and in shape measures, are more likely to be objects.
namespace objscan::discovery {

/// The paper's retrieval constants (section IV-B, "Recurrence"): the k = 10 most similar segments
/// among those within 25 % of the query's extent along each principal direction.
inline constexpr int kRecurrenceNeighbours = 10;
inline constexpr double kRecurrenceExtentWindow = 0.25;

/// One segment of the catalog as the recurrence look-up sees it.
struct RecurrenceEntry {
  std::int64_t scene_id = 0;
  /// Extents along the principal axes, decreasing, metres (Segment::extents).
  Eigen::Vector3f extents = Eigen::Vector3f::Zero();
  /// The five shape measures, raw, in recurrenceMeasures() order: compactness, symmetry,
  /// smoothness, local convexity, global convexity.
  std::array<double, 5> measures{};
  /// The catalog's id of the segment (Catalog::recurrenceEntries fills it); not used by the
  /// look-up itself.
  std::int64_t segment_id = 0;
};

/// One of the segments nearest to a query: which entry (index into the entries the index was
/// built from) and its distance in z-normalised measure units.
struct RecurrenceNeighbour {
  std::size_t entry = 0;
  double distance = 0.0;
};

/// The five shape measures that recurrence compares (every measure but recurrence itself).
inline std::array<double, 5> recurrenceMeasures(const ShapeMeasures& m) {
  return {m.compactness, m.symmetry, m.smoothness, m.local_convexity, m.global_convexity};
}

/// Recurrence look-ups against a fixed set of segments (in practice: every segment of every scene
/// in the catalog). Immutable after construction; const methods are safe from several threads.
class RecurrenceIndex {
 public:
  /// Takes the entries, computes each measure's mean and (population) standard deviation over all
  /// of them, and builds a kd-tree over their log-extents. A measure whose standard deviation is
  /// 0 or not finite contributes nothing to distances; a non-finite value counts as the mean.
  explicit RecurrenceIndex(std::vector<RecurrenceEntry> entries);
  ~RecurrenceIndex();
  RecurrenceIndex(RecurrenceIndex&&) noexcept;
  RecurrenceIndex& operator=(RecurrenceIndex&&) noexcept;
  RecurrenceIndex(const RecurrenceIndex&) = delete;
  RecurrenceIndex& operator=(const RecurrenceIndex&) = delete;

  /// The mean Euclidean distance, in z-normalised measure units, from `measures` to the `k`
  /// nearest entries of scenes other than `exclude_scene_id` whose every extent e_d satisfies
  /// |e_d - q_d| <= window * q_d (q = `extents`). Lower means the segment recurs more. Averages
  /// over fewer than k when fewer qualify; NaN when none does (also for a negative or non-finite
  /// query extent). Throws std::invalid_argument for k < 1 or a negative or NaN window.
  double recurrence(const Eigen::Vector3f& extents, const std::array<double, 5>& measures,
                    std::int64_t exclude_scene_id, int k = kRecurrenceNeighbours,
                    double window = kRecurrenceExtentWindow) const;

  /// The k nearest entries that recurrence() averages over, nearest first (ties by entry);
  /// empty when none qualifies. The paper's Fig. 6: a segment and the segments of other scenes
  /// most like it. Throws as recurrence() does.
  std::vector<RecurrenceNeighbour> nearest(const Eigen::Vector3f& extents,
                                           const std::array<double, 5>& measures,
                                           std::int64_t exclude_scene_id,
                                           int k = kRecurrenceNeighbours,
                                           double window = kRecurrenceExtentWindow) const;

  /// recurrence() for each query (its scene_id is ignored; `exclude_scene_id` applies to all),
  /// in parallel.
  std::vector<double> recurrences(const std::vector<RecurrenceEntry>& queries,
                                  std::int64_t exclude_scene_id, int k = kRecurrenceNeighbours,
                                  double window = kRecurrenceExtentWindow) const;

  /// The number of entries.
  std::size_t size() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace objscan::discovery
