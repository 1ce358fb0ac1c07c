#include "objscan/discovery/recurrence.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <nanoflann.hpp>

#include "point_index.h"

// The look-up. The paper's window, |e_d - q_d| <= w q_d along each of the three principal
// extents, is a box around q whose sides grow with q, so in log-extents it is a box of fixed
// shape: log e_d in [log q_d + log(1 - w), log q_d + log(1 + w)]. A kd-tree (nanoflann, as in
// point_index.h) over the entries' log-extents answers a radius search with the smallest ball
// that holds that box; the exact window test and the scene exclusion run on each point the search
// reaches, and the survivors' squared distances in z-normalised measure space go through a bounded
// max-heap of size k. The ball holds about 2.7 times the box's volume, so the search visits a few
// times the entries that qualify and never the whole catalog. (A kd-tree over extents and
// measures together cannot answer "k nearest in measures among those in the window" directly;
// filtering by size first is what the paper describes.)

namespace objscan::discovery {
namespace {

constexpr std::size_t kMeasures = 5;
/// Extents at or below this (metres) share one log-coordinate in the tree, so that a zero or
/// non-finite extent does not put -inf or NaN into it. The window test itself uses raw extents.
constexpr double kMinLogExtent = 1e-6;
/// Slack on the ball's radius, in log units, for the float rounding of the tree's coordinates:
/// the ball may hold a little more than the box, never less.
constexpr double kLogSlack = 1e-4;

float logExtent(float e) {
  return std::isfinite(e)
             ? static_cast<float>(std::log(std::max(static_cast<double>(e), kMinLogExtent)))
             : static_cast<float>(std::log(kMinLogExtent));
}

void checkArguments(int k, double window) {
  if (k < 1) {
    throw std::invalid_argument("recurrence needs k >= 1 neighbours, got " + std::to_string(k));
  }
  if (!(window >= 0.0)) {
    throw std::invalid_argument("the recurrence extent window must be a fraction >= 0, got " +
                                std::to_string(window));
  }
}

}  // namespace

struct RecurrenceIndex::Impl {
  using Cloud = PointCloudAdaptor;
  using Tree = PointTree;
  /// A squared measure distance and the entry it is to; ordered by distance, then entry, so
  /// that the k kept do not depend on the order the tree reaches them in.
  using Neighbour = std::pair<double, std::uint32_t>;

  /// A nanoflann result set that keeps, of the points the radius search reaches, those of other
  /// scenes inside the window, as a max-heap of the k smallest squared measure distances.
  class WindowNeighbours {
   public:
    using DistanceType = float;
    using IndexType = std::uint32_t;

    WindowNeighbours(const Impl& index, const Eigen::Vector3d& q, double window,
                     std::int64_t exclude, const std::array<double, kMeasures>& z_q, std::size_t k,
                     float radius_sq, std::vector<Neighbour>* heap)
        : index_(index),
          q_(q),
          window_(window),
          exclude_(exclude),
          z_q_(z_q),
          k_(k),
          radius_sq_(radius_sq),
          heap_(*heap) {
      heap_.clear();
    }

    bool full() const { return true; }
    float worstDist() const { return radius_sq_; }

    bool addPoint(float, std::uint32_t i) {
      if (index_.scene_ids[i] == exclude_) return true;
      const Eigen::Vector3f& e = index_.extents[i];
      for (int d = 0; d < 3; ++d) {
        if (!(std::abs(static_cast<double>(e[d]) - q_[d]) <= window_ * q_[d])) return true;
      }
      const double* z_i = &index_.z[i * kMeasures];
      double d2 = 0.0;
      for (std::size_t j = 0; j < kMeasures; ++j) d2 += (z_q_[j] - z_i[j]) * (z_q_[j] - z_i[j]);
      const Neighbour found{d2, i};
      if (heap_.size() < k_) {
        heap_.push_back(found);
        std::push_heap(heap_.begin(), heap_.end());
      } else if (found < heap_.front()) {
        std::pop_heap(heap_.begin(), heap_.end());
        heap_.back() = found;
        std::push_heap(heap_.begin(), heap_.end());
      }
      return true;
    }

   private:
    const Impl& index_;
    Eigen::Vector3d q_;
    double window_;
    std::int64_t exclude_;
    std::array<double, kMeasures> z_q_;
    std::size_t k_;
    float radius_sq_;
    std::vector<Neighbour>& heap_;
  };

  explicit Impl(std::vector<RecurrenceEntry> entries) {
    const std::size_t n = entries.size();
    if (n > std::numeric_limits<std::uint32_t>::max()) {
      throw std::length_error("a recurrence index holds at most 2^32 - 1 segments");
    }
    // Per-measure mean and population standard deviation over the finite values, two passes.
    for (std::size_t j = 0; j < kMeasures; ++j) {
      double sum = 0.0;
      std::size_t count = 0;
      for (const RecurrenceEntry& e : entries) {
        if (std::isfinite(e.measures[j])) {
          sum += e.measures[j];
          ++count;
        }
      }
      mean[j] = count > 0 ? sum / static_cast<double>(count) : 0.0;
      double squares = 0.0;
      for (const RecurrenceEntry& e : entries) {
        if (std::isfinite(e.measures[j]))
          squares += (e.measures[j] - mean[j]) * (e.measures[j] - mean[j]);
      }
      const double sd = count > 0 ? std::sqrt(squares / static_cast<double>(count)) : 0.0;
      inv_sd[j] = (sd > 0.0 && std::isfinite(sd)) ? 1.0 / sd : 0.0;
    }
    scene_ids.resize(n);
    extents.resize(n);
    log_extents.resize(n);
    z.resize(n * kMeasures);
    for (std::size_t i = 0; i < n; ++i) {
      scene_ids[i] = entries[i].scene_id;
      extents[i] = entries[i].extents;
      for (int d = 0; d < 3; ++d) log_extents[i][d] = logExtent(entries[i].extents[d]);
      const std::array<double, kMeasures> zi = normalised(entries[i].measures);
      std::copy(zi.begin(), zi.end(), z.begin() + static_cast<std::ptrdiff_t>(i * kMeasures));
    }
    cloud.points = &log_extents;
    tree = std::make_unique<Tree>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  }

  std::array<double, kMeasures> normalised(const std::array<double, kMeasures>& m) const {
    std::array<double, kMeasures> out{};
    for (std::size_t j = 0; j < kMeasures; ++j) {
      out[j] = std::isfinite(m[j]) ? (m[j] - mean[j]) * inv_sd[j] : 0.0;
    }
    return out;
  }

  /// The k nearest qualifying entries into `heap` (a max-heap, unordered otherwise).
  void search(const Eigen::Vector3f& extents_q, const std::array<double, kMeasures>& measures,
              std::int64_t exclude, int k, double window, std::vector<Neighbour>* heap) const {
    heap->clear();
    const Eigen::Vector3d q = extents_q.cast<double>();
    if (!q.allFinite() || (q.array() < 0.0).any() || scene_ids.empty()) return;
    // The window's box in log-extents (clamped as the tree's coordinates are) and the ball
    // around its centre that holds it.
    Eigen::Vector3f centre;
    double radius_sq = 0.0;
    for (int d = 0; d < 3; ++d) {
      const double lo = std::log(std::max(q[d] * (1.0 - window), kMinLogExtent));
      const double hi = std::log(std::max(q[d] * (1.0 + window), kMinLogExtent));
      centre[d] = static_cast<float>(0.5 * (lo + hi));
      const double half = 0.5 * (hi - lo) + kLogSlack;
      radius_sq += half * half;
    }
    WindowNeighbours found(*this, q, window, exclude, normalised(measures),
                           static_cast<std::size_t>(k), static_cast<float>(radius_sq), heap);
    tree->findNeighbors(found, centre.data(), nanoflann::SearchParams());
  }

  double query(const Eigen::Vector3f& extents_q, const std::array<double, kMeasures>& measures,
               std::int64_t exclude, int k, double window, std::vector<Neighbour>* heap) const {
    search(extents_q, measures, exclude, k, window, heap);
    if (heap->empty()) return std::numeric_limits<double>::quiet_NaN();
    double sum = 0.0;
    for (const Neighbour& n : *heap) sum += std::sqrt(n.first);
    return sum / static_cast<double>(heap->size());
  }

  std::vector<std::int64_t> scene_ids;
  std::vector<Eigen::Vector3f> extents;      ///< raw, metres
  std::vector<Eigen::Vector3f> log_extents;  ///< the tree's points
  std::vector<double> z;                     ///< z-normalised measures, kMeasures per entry
  std::array<double, kMeasures> mean{};
  std::array<double, kMeasures> inv_sd{};  ///< 0 for a measure that does not count
  Cloud cloud;  ///< points at log_extents; Impl stays put (held by pointer), so this stays valid
  std::unique_ptr<Tree> tree;
};

RecurrenceIndex::RecurrenceIndex(std::vector<RecurrenceEntry> entries)
    : impl_(std::make_unique<Impl>(std::move(entries))) {}
RecurrenceIndex::~RecurrenceIndex() = default;
RecurrenceIndex::RecurrenceIndex(RecurrenceIndex&&) noexcept = default;
RecurrenceIndex& RecurrenceIndex::operator=(RecurrenceIndex&&) noexcept = default;

double RecurrenceIndex::recurrence(const Eigen::Vector3f& extents,
                                   const std::array<double, 5>& measures,
                                   std::int64_t exclude_scene_id, int k, double window) const {
  checkArguments(k, window);
  std::vector<Impl::Neighbour> heap;
  heap.reserve(static_cast<std::size_t>(k));
  return impl_->query(extents, measures, exclude_scene_id, k, window, &heap);
}

std::vector<RecurrenceNeighbour> RecurrenceIndex::nearest(const Eigen::Vector3f& extents,
                                                          const std::array<double, 5>& measures,
                                                          std::int64_t exclude_scene_id, int k,
                                                          double window) const {
  checkArguments(k, window);
  std::vector<Impl::Neighbour> heap;
  heap.reserve(static_cast<std::size_t>(k));
  impl_->search(extents, measures, exclude_scene_id, k, window, &heap);
  std::sort_heap(heap.begin(), heap.end());
  std::vector<RecurrenceNeighbour> out;
  out.reserve(heap.size());
  for (const Impl::Neighbour& n : heap) out.push_back({n.second, std::sqrt(n.first)});
  return out;
}

std::vector<double> RecurrenceIndex::recurrences(const std::vector<RecurrenceEntry>& queries,
                                                 std::int64_t exclude_scene_id, int k,
                                                 double window) const {
  checkArguments(k, window);
  std::vector<double> out(queries.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.size()),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      std::vector<Impl::Neighbour> heap;
                      heap.reserve(static_cast<std::size_t>(k));
                      for (std::size_t i = range.begin(); i != range.end(); ++i) {
                        out[i] = impl_->query(queries[i].extents, queries[i].measures,
                                              exclude_scene_id, k, window, &heap);
                      }
                    });
  return out;
}

std::size_t RecurrenceIndex::size() const { return impl_->scene_ids.size(); }

}  // namespace objscan::discovery
