// Memory on a large scene (the hostile-input audit): a mesh of about 3 million vertices, made of copies of a fused
// scene laid side by side, goes through `objscan info`, `objscan discover` and `objscan render`,
// each in its own process; the figure is the kernel's peak resident set of that process
// (ru_maxrss, taken by peak_memory). The peer: Open3D reading the same file, also in a process of
// its own.
//
// Usage: large_mesh_bench SCENE.ply [--vertices N]   (N defaults to 3000000)

#include <unistd.h>

#include <open3d/io/TriangleMeshIO.h>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "build_paths.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/triangle_mesh.h"

namespace fs = std::filesystem;

namespace {

struct ChildRun {
  int status = -1;
  double seconds = 0.0;
  double peak_mb = 0.0;
};

/// Runs `argv` under peak_memory (see peak_memory.cpp for why not from this process) and reads
/// its figures.
ChildRun measured(std::vector<std::string> argv) {
  argv.insert(argv.begin(), OBJSCAN_PEAK_MEMORY);
  std::string command;
  for (const std::string& a : argv) {  // each in single quotes; a quote in it as '\''
    command.push_back('\'');
    for (const char c : a) {
      if (c == '\'') {
        command.append("'\\''");
      } else {
        command.push_back(c);
      }
    }
    command.append("' ");
  }
  command.append("2>/dev/null");
  FILE* out = popen(command.c_str(), "r");
  if (out == nullptr) throw std::runtime_error("cannot run " + argv[0]);
  ChildRun r;
  char line[4096];
  long kb = 0;
  while (std::fgets(line, sizeof line, out) != nullptr) {
    std::sscanf(line, "peak_memory %ld %lf %d", &kb, &r.seconds, &r.status);
  }
  pclose(out);
  r.peak_mb = static_cast<double>(kb) / 1024.0;
  return r;
}

ChildRun runObjscan(std::vector<std::string> args) {
  args.insert(args.begin(), {OBJSCAN_EXE, "--quiet"});
  return measured(args);
}

/// Copies of `scene` on a grid, each moved past the last by its width and a 0.5 m gap, until the
/// mesh has at least `vertices` vertices.
objscan::TriangleMesh tiled(const objscan::TriangleMesh& scene, std::size_t vertices) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = -lo;
  for (const auto& p : scene.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3f step = (hi - lo) + Eigen::Vector3f::Constant(0.5f);
  const std::size_t copies = (vertices + scene.positions.size() - 1) / scene.positions.size();
  const auto side = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(copies))));
  objscan::TriangleMesh out;
  for (std::size_t c = 0; c < copies; ++c) {
    const Eigen::Vector3f offset(step.x() * static_cast<float>(c % side), 0.0f,
                                 step.z() * static_cast<float>(c / side));
    const auto base = static_cast<std::int32_t>(out.positions.size());
    for (const auto& p : scene.positions) out.positions.push_back(p + offset);
    out.normals.insert(out.normals.end(), scene.normals.begin(), scene.normals.end());
    out.colors.insert(out.colors.end(), scene.colors.begin(), scene.colors.end());
    for (const auto& t : scene.triangles)
      out.triangles.push_back(t + Eigen::Vector3i::Constant(base));
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::string(argv[1]) == "--open3d-read") {  // the peer, run by peak_memory
    open3d::geometry::TriangleMesh mesh;
    return open3d::io::ReadTriangleMesh(argv[2], mesh) && !mesh.vertices_.empty() ? 0 : 1;
  }
  if (argc < 2) {
    std::fprintf(stderr, "usage: large_mesh_bench SCENE.ply [--vertices N]\n");
    return 2;
  }
  std::size_t target = 3000000;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (std::string(argv[i]) == "--vertices") target = std::strtoull(argv[i + 1], nullptr, 10);
  }
  const fs::path dir = fs::temp_directory_path() / ("large_mesh_bench-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path big = dir / "large.ply";
  {
    const objscan::TriangleMesh mesh = tiled(objscan::readPly(argv[1]), target);
    objscan::writePly(big, mesh);
    std::printf("mesh: %zu vertices, %zu triangles, %.0f MB of PLY (%s tiled)\n",
                mesh.positions.size(), mesh.triangles.size(),
                static_cast<double>(fs::file_size(big)) / 1e6, argv[1]);
  }
  const double file_mb = static_cast<double>(fs::file_size(big)) / (1024.0 * 1024.0);

  const ChildRun open3d =
      measured({fs::read_symlink("/proc/self/exe").string(), "--open3d-read", big.string()});
  const ChildRun info = runObjscan({"info", big.string()});
  const ChildRun discover =
      runObjscan({"discover", big.string(), "--no-catalog", "--out", (dir / "results").string()});
  const ChildRun render = runObjscan({"render", (dir / "results").string()});

  std::printf("\n%-34s %8s %9s %12s\n", "process", "seconds", "peak MB", "x file size");
  const auto row = [&](const char* name, const ChildRun& r) {
    std::printf("%-34s %8.1f %9.0f %12.2f%s\n", name, r.seconds, r.peak_mb, r.peak_mb / file_mb,
                r.status == 0 ? "" : "  (FAILED)");
  };
  row("Open3D ReadTriangleMesh (peer)", open3d);
  row("objscan info", info);
  row("objscan discover --no-catalog", discover);
  row("objscan render", render);
  std::printf("\nobjscan info / Open3D read: %.2fx the memory\n", info.peak_mb / open3d.peak_mb);
  fs::remove_all(dir);
  return info.status == 0 && discover.status == 0 && render.status == 0 ? 0 : 1;
}
