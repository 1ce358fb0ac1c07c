// `objscan info` on the real data in ../shared/data (label: data).

#include <gtest/gtest.h>

#include "test_support.h"

namespace objscan {
namespace {

TEST(CliRealData, InfoOnYcbMugReports8188VerticesAnd16384Faces) {
  const std::string mug = std::string(OBJSCAN_DATA_DIR) + "/ycb_meshes/025_mug.ply";
  const testing::ProcessResult r = testing::runProcess({OBJSCAN_EXE, "info", mug});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("vertices      8188 (normals: yes, colours: no)"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("faces         16384 triangles"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ignored       vertex.s, vertex.t"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace objscan
