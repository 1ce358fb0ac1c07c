#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "build_paths.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/triangle_mesh.h"

namespace objscan::testing {

/// A fresh directory under the system temp folder, removed with everything in it on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

void writeBytes(const std::filesystem::path& path, const std::string& bytes);

/// How many entries a folder holds (not recursive).
std::size_t entryCount(const std::filesystem::path& dir);

/// While alive, files this process writes are limited to `bytes` (RLIMIT_FSIZE): a write past
/// the limit fails with EFBIG, as on a full disk, and that works for root too (directory
/// permissions do not). SIGXFSZ is ignored meanwhile; both are restored on destruction.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(std::uint64_t bytes);
  ~FileSizeLimit();
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  std::uint64_t saved_soft_limit_ = 0;
  void (*saved_handler_)(int) = nullptr;
};
std::string readBytes(const std::filesystem::path& path);

/// A pinhole camera of the given size and focal length (fx = fy) with its principal point at the
/// image centre, ((width - 1) / 2, (height - 1) / 2).
Intrinsics centredCamera(int width, int height, double focal_px);

/// An axis-aligned cube of side `side_m` centred at the origin: 8 vertices, 12 outward triangles.
TriangleMesh makeCube(float side_m = 1.0f);

/// A height field z = f(x, y) over [-half, half]^2 on an n x n grid, two triangles per cell,
/// counter-clockwise seen from above, with area-weighted vertex normals (pointing up).
TriangleMesh makeHeightField(int n, float half, const std::function<float(float, float)>& f);

/// Two triangles per cell of a grid of `rows` rows of `n` vertices each (vertex j * n + i), wound
/// as makeHeightField's: counter-clockwise seen from the side that i x j points to.
void addGridTriangles(TriangleMesh& mesh, int rows, int n);

/// A mesh with random positions (including awkward floats: tiny, huge, negative zero,
/// subnormal), unit normals, colours with object labels, and random non-degenerate triangles;
/// fixed seed.
TriangleMesh makeRandomMesh(std::uint32_t seed, std::size_t vertices, std::size_t triangles,
                            bool with_normals = true, bool with_colors = true);

/// True when both meshes hold bit-identical floats (so -0.0 != 0.0) and equal everything else.
bool bitwiseEqual(const TriangleMesh& a, const TriangleMesh& b);

/// Expects `action` to throw objscan::InputError with a message that starts with "<path>: " and
/// contains `needle` (gtest failures otherwise).
void expectInputError(const std::function<void()>& action, const std::filesystem::path& path,
                      const std::string& needle);

/// Runs a program with arguments, stdout and stderr captured separately, no terminal attached.
struct ProcessResult {
  int exit_code = -1;  ///< exit status, or 128 + signal number when killed by a signal
  std::string out;
  std::string err;
};
ProcessResult runProcess(const std::vector<std::string>& argv);

/// Extras for runProcess: environment variables added to the child's, and a signal sent once the
/// child's stderr contains `signal_when` (then after `signal_delay_ms`).
struct ProcessOptions {
  std::vector<std::string> env;  ///< "NAME=value"
  int signal = 0;                ///< e.g. SIGINT; 0 = none
  std::string signal_when;
  int signal_delay_ms = 0;
  std::filesystem::path cwd;  ///< the child's working directory; empty = this process's
};
ProcessResult runProcess(const std::vector<std::string>& argv, const ProcessOptions& options);

/// A 7-Scenes / 3DMatch file name: sevenScenesFrameName(7, "depth.png") = "frame-000007.depth.png".
std::string sevenScenesFrameName(int number, const std::string& suffix);

/// Lines of `text` without their '\n' (a final line without '\n' counts too).
std::vector<std::string> lines(const std::string& text);

}  // namespace objscan::testing
