#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "disjoint_sets.h"
#include "objscan/discovery/mesh_graph.h"

namespace objscan::discovery {

/// The vertices of `members` grouped into regions connected by the graph's edges: per vertex,
/// its region's representative (meaningful only for members). Support regions (supports.cpp)
/// and the regions off the supports that candidates belong to (context.cpp).
inline std::vector<std::int32_t> connectedRegions(const MeshGraph& graph,
                                                  const std::vector<std::uint8_t>& members) {
  DisjointSets sets(members.size());
  for (const MeshEdge& e : graph.edges) {
    if (!members[static_cast<std::size_t>(e.a)] || !members[static_cast<std::size_t>(e.b)]) {
      continue;
    }
    const std::int32_t a = sets.find(e.a), b = sets.find(e.b);
    if (a != b) sets.attach(a, b);
  }
  std::vector<std::int32_t> region(members.size());
  for (std::size_t v = 0; v < region.size(); ++v) {
    region[v] = sets.find(static_cast<std::int32_t>(v));
  }
  return region;
}

}  // namespace objscan::discovery
