#pragma once

// Stratified random draws for training and evaluation (private to discovery).

#include <algorithm>
#include <array>
#include <cstddef>
#include <random>
#include <vector>

namespace objscan::discovery {

/// The indices of the non-objects (element 0) and the objects (element 1, label 1), each in
/// increasing order and then shuffled with `rng`: non-objects first, so the draws are repeatable.
inline std::array<std::vector<std::size_t>, 2> shuffledByClass(const std::vector<int>& labels,
                                                               std::mt19937_64& rng) {
  std::array<std::vector<std::size_t>, 2> by_class;
  for (int c = 0; c < 2; ++c) {
    for (std::size_t i = 0; i < labels.size(); ++i) {
      if ((labels[i] == 1) == (c == 1)) by_class[c].push_back(i);
    }
    std::shuffle(by_class[c].begin(), by_class[c].end(), rng);
  }
  return by_class;
}

}  // namespace objscan::discovery
