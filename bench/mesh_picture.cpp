// Renders a fused mesh off-screen for the README: the mesh's colours on the left, its shape
// (Lambert-shaded grey) on the right, both seen from a camera of its trajectory pulled back along
// the viewing direction so that more of the scene fits.
//
//   mesh_picture MESH.ply TRAJECTORY.txt OUT.png [--pose K] [--back M]
//
// K picks the trajectory's pose (default: the middle one), M the pull-back in metres (0.3).
// The README's fusion picture comes from
//   objscan fuse ../shared/data/tum_fr2_desk_50 --out /tmp/x
//   build/bench/mesh_picture /tmp/x/mesh.ply /tmp/x/trajectory.txt docs/fused_tum_desk.png

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "bench_main.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"
#include "objscan/render/offscreen_renderer.h"

namespace {

int run(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr,
                 "usage: mesh_picture MESH.ply TRAJECTORY.txt OUT.png [--pose K] "
                 "[--back M]\n");
    return 2;
  }
  const std::string out = argv[3];
  long pose_index = -1;
  float back_m = 0.3f;
  for (int i = 4; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--pose") {
      pose_index = std::atol(argv[i + 1]);
    } else if (flag == "--back") {
      back_m = static_cast<float>(std::atof(argv[i + 1]));
    } else {
      std::fprintf(stderr, "mesh_picture: unknown option %s\n", flag.c_str());
      return 2;
    }
  }
  objscan::TriangleMesh mesh = objscan::readPly(argv[1]);
  const objscan::Trajectory trajectory = objscan::readTumTrajectory(argv[2]);
  if (trajectory.empty()) throw std::runtime_error(std::string(argv[2]) + ": no poses");
  const std::size_t k = pose_index >= 0 && static_cast<std::size_t>(pose_index) < trajectory.size()
                            ? static_cast<std::size_t>(pose_index)
                            : trajectory.size() / 2;
  objscan::Pose T_W_C = trajectory.poses[k].T_W_C;
  T_W_C.translation() -= back_m * T_W_C.linear().col(2);

  objscan::Intrinsics intrinsics;  // 640x480, a field of view like the Xtion's
  objscan::render::OffscreenRenderer renderer(intrinsics, 0.05f, 20.0f);
  renderer.setMesh(mesh);
  const cv::Mat colored = renderer.render(T_W_C).color_rgb;
  mesh.colors.clear();
  renderer.setMesh(mesh);
  const cv::Mat shape = renderer.render(T_W_C).color_rgb;

  cv::Mat both;
  cv::hconcat(colored, shape, both);
  cv::cvtColor(both, both, cv::COLOR_RGB2BGR);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", both, png)) throw std::runtime_error("could not encode the PNG");
  objscan::writeFileAtomically(
      out, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  std::printf("%s: %zu vertices seen from pose %zu of %zu, pulled back %.2f m\n", out.c_str(),
              mesh.positions.size(), k, trajectory.size(), static_cast<double>(back_m));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("mesh_picture", run, argc, argv);
}
