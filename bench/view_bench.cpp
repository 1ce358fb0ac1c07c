// What objscan view and the report's inline view cost on a large mesh: the preview by vertex
// clustering (decimateByClustering) against Open3D's SimplifyVertexClustering with the same cell
// on the same mesh, and the binary mesh the browser receives against the PLY file.
//
//   build/bench/view_bench [mesh.ply]   (default: a 1.5 m wavy square of 3.2 million triangles)

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include <open3d/geometry/TriangleMesh.h>
#include <open3d/utility/Logging.h>

#include "bench_main.h"
#include "objscan/core/mesh_decimation.h"
#include "objscan/core/ply_io.h"
#include "objscan/report/mesh_view.h"

namespace objscan::bench {
namespace {

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

/// n × n vertices over 1.5 m, gently waved, coloured, with normals.
TriangleMesh wave(int n) {
  TriangleMesh mesh;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const float x = 1.5f * static_cast<float>(i) / static_cast<float>(n - 1) - 0.75f;
      const float y = 1.5f * static_cast<float>(j) / static_cast<float>(n - 1) - 0.75f;
      mesh.positions.emplace_back(x, y, 0.03f * std::sin(9 * x) * std::cos(7 * y));
      mesh.colors.emplace_back(static_cast<std::uint8_t>(i % 256), 90,
                               static_cast<std::uint8_t>(j % 256));
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i;
      mesh.triangles.emplace_back(a, a + 1, a + n + 1);
      mesh.triangles.emplace_back(a, a + n + 1, a + n);
    }
  }
  mesh.computeNormals();
  return mesh;
}

int run(int argc, char** argv) {
  open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
  const TriangleMesh mesh = argc > 1 ? readPly(argv[1]) : wave(1265);
  std::printf("mesh: %zu vertices, %zu triangles (%s)\n", mesh.positions.size(),
              mesh.triangles.size(), argc > 1 ? argv[1] : "synthetic wave");
  open3d::geometry::TriangleMesh o3d;
  for (const auto& p : mesh.positions) o3d.vertices_.push_back(p.cast<double>());
  for (const auto& t : mesh.triangles) o3d.triangles_.push_back(t);
  for (const auto& c : mesh.colors) o3d.vertex_colors_.push_back(c.cast<double>() / 255.0);
  for (const auto& n : mesh.normals) o3d.vertex_normals_.push_back(n.cast<double>());

  const auto start = std::chrono::steady_clock::now();
  const report::ViewMesh full = report::viewMesh(mesh, {}, "", mesh.triangles.size());
  const std::string full_bytes = report::meshViewPayload(full);
  std::printf("undecimated payload: %.1f MB (%.1f bytes a triangle), built in %.0f ms\n",
              full_bytes.size() / 1e6, static_cast<double>(full_bytes.size()) / mesh.triangles.size(),
              msSince(start));
  std::printf("%10s %12s %12s %10s %12s %12s %8s\n", "limit", "objscan ms", "triangles",
              "cell mm", "Open3D ms", "triangles", "ratio");
  for (const std::size_t limit : {1'000'000u, 250'000u, 100'000u}) {
    if (limit >= mesh.triangles.size()) continue;
    auto t0 = std::chrono::steady_clock::now();
    const DecimatedMesh ours = decimateByClustering(mesh, limit);
    const double ours_ms = msSince(t0);
    t0 = std::chrono::steady_clock::now();
    const auto theirs = o3d.SimplifyVertexClustering(ours.cell_m);
    const double theirs_ms = msSince(t0);
    std::printf("%10zu %12.0f %12zu %10.2f %12.0f %12zu %8.2f\n", limit, ours_ms,
                ours.mesh.triangles.size(), 1000.0 * ours.cell_m, theirs_ms,
                theirs->triangles_.size(), theirs_ms / ours_ms);
  }
  std::printf("ratio: Open3D's time over objscan's for the same cell (objscan's includes finding "
              "the cell: one clustering per try)\n");
  return 0;
}

}  // namespace
}  // namespace objscan::bench

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("view_bench", objscan::bench::run, argc, argv);
}
