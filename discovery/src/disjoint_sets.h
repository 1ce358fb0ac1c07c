#pragma once

#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

namespace objscan::discovery {

/// Union-find parents over vertex indices, with path halving: FH's components (segmentation.cpp)
/// and support regions (supports.cpp). Only the parents: callers keep what a root carries.
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) : parent_(n) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }

  std::int32_t find(std::int32_t x) {
    while (parent_[static_cast<std::size_t>(x)] != x) {
      auto& p = parent_[static_cast<std::size_t>(x)];
      p = parent_[static_cast<std::size_t>(p)];  // path halving
      x = p;
    }
    return x;
  }

  /// Hangs the root `child` under the root `parent`.
  void attach(std::int32_t child, std::int32_t parent) {
    parent_[static_cast<std::size_t>(child)] = parent;
  }

  /// Asks the memory system for x's parent ahead of its use.
  void prefetch(std::int32_t x) const { __builtin_prefetch(&parent_[static_cast<std::size_t>(x)]); }

  std::size_t size() const { return parent_.size(); }

 private:
  std::vector<std::int32_t> parent_;
};

}  // namespace objscan::discovery
