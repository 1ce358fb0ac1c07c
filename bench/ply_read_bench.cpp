// PLY reading: objscan's reader against PCL's PLYReader, PCL's VTK-based reader and Open3D's
// rply-based reader, on the same files in the same run.
//
// The input is a torus mesh at the paper's scene size (Karpathy et al. 2013: ~200k vertices,
// ~400k faces) with normals and colours, written once as binary and once as ASCII PLY. Each reader
// loads it into the typed arrays a pipeline needs (positions, normals, colours, triangles), so
// PCL's PCLPointCloud2 -> PointCloud conversion is part of its time. Medians of --repeat runs.
//
// Then a robustness probe: each reader gets truncated copies of both files (a forked child per
// attempt, so a crash is seen rather than taken down with it) and the result is printed: a clean
// error, a crash, or the file accepted without complaint.
//
//   ply_read_bench [--faces N] [--repeat R]

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>
#include <open3d/utility/Logging.h>
#include <pcl/PolygonMesh.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>
#include <pcl/io/ply_io.h>
#include <pcl/io/vtk_lib_io.h>
#include <pcl/point_types.h>

#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"

namespace fs = std::filesystem;

namespace {

/// What a reader delivered: counts, or ok = false when it reported failure.
struct Loaded {
  bool ok = false;
  std::size_t vertices = 0;
  std::size_t triangles = 0;
};

struct Reader {
  const char* name;
  std::function<Loaded(const std::string&)> read;
};

Loaded readObjscan(const std::string& path) {
  try {
    const objscan::TriangleMesh m = objscan::readPly(path);
    return {true, m.positions.size(), m.triangles.size()};
  } catch (const objscan::InputError&) {
    return {};
  }
}

Loaded fromPclMesh(const pcl::PolygonMesh& mesh) {
  pcl::PointCloud<pcl::PointXYZRGBNormal> cloud;
  pcl::fromPCLPointCloud2(mesh.cloud, cloud);
  std::vector<Eigen::Vector3i> triangles;
  triangles.reserve(mesh.polygons.size());
  for (const auto& p : mesh.polygons) {
    if (p.vertices.size() == 3) triangles.emplace_back(p.vertices[0], p.vertices[1], p.vertices[2]);
  }
  return {true, cloud.size(), triangles.size()};
}

Loaded readPcl(const std::string& path) {
  pcl::PolygonMesh mesh;
  if (pcl::io::loadPLYFile(path, mesh) != 0) return {};
  return fromPclMesh(mesh);
}

Loaded readPclVtk(const std::string& path) {
  pcl::PolygonMesh mesh;
  if (pcl::io::loadPolygonFilePLY(path, mesh) == 0) return {};  // returns the number of polygons
  return fromPclMesh(mesh);
}

Loaded readOpen3d(const std::string& path) {
  open3d::geometry::TriangleMesh mesh;
  if (!open3d::io::ReadTriangleMesh(path, mesh)) return {};
  return {true, mesh.vertices_.size(), mesh.triangles_.size()};
}

/// A torus with `faces` triangles (rounded to the grid), normals and a colour gradient.
objscan::TriangleMesh makeTorus(std::size_t faces) {
  const int rings = static_cast<int>(std::sqrt(static_cast<double>(faces) / 2.0 / 2.0));
  const int segments = static_cast<int>(faces / 2 / static_cast<std::size_t>(rings));
  const float big_r = 0.3f, small_r = 0.1f;
  objscan::TriangleMesh m;
  for (int i = 0; i < rings; ++i) {
    const float u =
        2.0f * std::numbers::pi_v<float> * static_cast<float>(i) / static_cast<float>(rings);
    for (int j = 0; j < segments; ++j) {
      const float v =
          2.0f * std::numbers::pi_v<float> * static_cast<float>(j) / static_cast<float>(segments);
      const Eigen::Vector3f n(std::cos(u) * std::cos(v), std::sin(u) * std::cos(v), std::sin(v));
      const Eigen::Vector3f c(big_r * std::cos(u), big_r * std::sin(u), 0.0f);
      m.positions.push_back(c + small_r * n);
      m.normals.push_back(n);
      m.colors.emplace_back(static_cast<std::uint8_t>(255 * i / rings),
                            static_cast<std::uint8_t>(255 * j / segments), 128);
    }
  }
  auto id = [&](int i, int j) { return (i % rings) * segments + (j % segments); };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      m.triangles.emplace_back(id(i, j), id(i + 1, j), id(i + 1, j + 1));
      m.triangles.emplace_back(id(i, j), id(i + 1, j + 1), id(i, j + 1));
    }
  }
  return m;
}

double medianMs(const Reader& reader, const std::string& path, int repeat, Loaded& loaded) {
  std::vector<double> ms;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    loaded = reader.read(path);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

/// Runs the reader on `path` in a child process; describes what happened.
std::string probe(const Reader& reader, const std::string& path) {
  std::fflush(stdout);
  const pid_t pid = ::fork();
  if (pid == 0) {
    // Quiet the child: libraries print their own warnings.
    std::freopen("/dev/null", "w", stderr);
    std::freopen("/dev/null", "w", stdout);
    const Loaded l = reader.read(path);
    // Exit code 10 = reported an error; 11 = accepted. Counts go through a file.
    std::ofstream(path + ".result") << l.vertices << " " << l.triangles;
    std::_Exit(l.ok ? 11 : 10);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (WIFSIGNALED(status))
    return std::string("CRASH (signal ") + std::to_string(WTERMSIG(status)) + ")";
  if (WEXITSTATUS(status) == 10) return "error reported";
  std::size_t v = 0, t = 0;
  std::ifstream(path + ".result") >> v >> t;
  return "ACCEPTED: " + std::to_string(v) + " vertices, " + std::to_string(t) + " triangles";
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t faces = 400000;
  int repeat = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--faces")
      faces = std::stoul(argv[i + 1]);
    else if (flag == "--repeat")
      repeat = std::max(1, std::atoi(argv[i + 1]));
    else {
      std::fprintf(stderr, "usage: ply_read_bench [--faces N] [--repeat R]\n");
      return 2;
    }
  }
  objscan::log::setLevel(objscan::log::Level::kError);
  open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
  pcl::console::setVerbosityLevel(pcl::console::L_ERROR);

  char tmpl[] = "/tmp/ply_read_bench-XXXXXX";
  const fs::path dir = ::mkdtemp(tmpl);
  const objscan::TriangleMesh torus = makeTorus(faces);
  const std::string bin = (dir / "torus_binary.ply").string();
  const std::string ascii = (dir / "torus_ascii.ply").string();
  objscan::writePly(bin, torus, objscan::PlyFormat::kBinaryLittleEndian);
  objscan::writePly(ascii, torus, objscan::PlyFormat::kAscii);

  const std::vector<Reader> readers = {
      {"objscan readPly", readObjscan},
      {"PCL loadPLYFile (PLYReader)", readPcl},
      {"PCL loadPolygonFilePLY (VTK)", readPclVtk},
      {"Open3D ReadTriangleMesh (rply)", readOpen3d},
  };

  std::printf(
      "PLY read: %zu vertices, %zu triangles, normals + colours; median of %d runs, one thread\n",
      torus.positions.size(), torus.triangles.size(), repeat);
  std::printf("%-32s %-7s %10s %9s  %s\n", "reader", "file", "ms", "x objscan", "result");
  for (const auto& [label, path] : {std::pair{"binary", bin}, std::pair{"ascii", ascii}}) {
    std::printf("  (%s: %.1f MB)\n", label, static_cast<double>(fs::file_size(path)) / 1e6);
    double ours_ms = 0.0;
    for (const Reader& reader : readers) {
      Loaded loaded;
      const double ms = medianMs(reader, path, repeat, loaded);
      if (&reader == &readers.front()) ours_ms = ms;
      const bool complete = loaded.ok && loaded.vertices == torus.positions.size() &&
                            loaded.triangles == torus.triangles.size();
      std::printf("%-32s %-7s %10.1f %9.2f  %s\n", reader.name, label, ms, ms / ours_ms,
                  complete ? "complete" : "INCOMPLETE");
    }
  }

  std::printf("\nTruncated files (what each reader does with a file cut short):\n");
  const std::string bytes_bin = [&] {
    std::ifstream in(bin, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  const std::string bytes_ascii = [&] {
    std::ifstream in(ascii, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  struct Cut {
    const char* label;
    const std::string* bytes;
    double keep;
  };
  const Cut cuts[] = {{"binary cut at 50%", &bytes_bin, 0.5},
                      {"binary, last 7 bytes missing", &bytes_bin, -7},
                      {"ascii cut at 50%", &bytes_ascii, 0.5},
                      {"ascii, last 7 bytes missing", &bytes_ascii, -7},
                      {"ascii, cut inside the last number (2 bytes missing)", &bytes_ascii, -2}};
  for (const Cut& cut : cuts) {
    const std::size_t keep =
        cut.keep > 0 ? static_cast<std::size_t>(static_cast<double>(cut.bytes->size()) * cut.keep)
                     : cut.bytes->size() - static_cast<std::size_t>(-cut.keep);
    const std::string path = (dir / "cut.ply").string();
    std::ofstream(path, std::ios::binary)
        .write(cut.bytes->data(), static_cast<std::streamsize>(keep));
    std::printf("  %s:\n", cut.label);
    for (const Reader& reader : readers)
      std::printf("    %-32s %s\n", reader.name, probe(reader, path).c_str());
  }
  fs::remove_all(dir);
  return 0;
}
