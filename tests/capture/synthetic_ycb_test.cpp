// Synthetic scenes built from the real YCB meshes in ../shared/data (label: data).

#include <gtest/gtest.h>

#include <filesystem>

#include "build_paths.h"
#include "objscan/capture/synthetic/synthetic_recording.h"
#include "objscan/render/offscreen_renderer.h"

namespace objscan::capture {
namespace {

TEST(SyntheticYcb, EveryObjectIsSeenAlongThePathWithYcbObjects) {
  // The case an earlier review found with one cup hidden all along the path: counter, 20 objects,
  // seed 4, built-ins and YCB meshes.
  SceneConfig config;
  config.preset = ScenePreset::kCounter;
  config.objects = 20;
  config.seed = 4;
  config.object_dir = std::filesystem::path(OBJSCAN_DATA_DIR) / "ycb_meshes";
  const SceneAndPath composed =
      composeSceneSeenAlongPath(config, HandheldPathConfig{}, Intrinsics::xtionDefault());
  ASSERT_EQ(composed.scene.objects.size(), 20u);
  int from_ycb = 0;
  for (const SceneObject& o : composed.scene.objects)
    from_ycb += o.name.find('_') != std::string::npos;
  EXPECT_GT(from_ycb, 5) << "25 of the 36 candidates are YCB meshes";
  render::OffscreenRenderer renderer(Intrinsics::xtionDefault());
  renderer.setMesh(composed.scene.mesh);
  std::vector<int> seen(21, 0);
  for (std::size_t i = 0; i < composed.path.size(); i += 5) {
    const cv::Mat label = renderer.render(composed.path.poses[i].T_W_C).label;
    for (int v = 0; v < label.rows; ++v) {
      for (int u = 0; u < label.cols; ++u)
        ++seen[static_cast<std::size_t>(label.at<std::int32_t>(v, u))];
    }
  }
  for (const SceneObject& o : composed.scene.objects) {
    EXPECT_GT(seen[static_cast<std::size_t>(o.id)], 20) << o.name << " never seen";
  }
}

}  // namespace
}  // namespace objscan::capture
