#include "objscan/core/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>

#include <Eigen/Geometry>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan {
namespace {

using testing::TempDir;
using testing::writeBytes;

void expectReadError(const std::filesystem::path& path, const std::string& needle) {
  testing::expectInputError([&] { readTumTrajectory(path); }, path, needle);
}

TEST(Trajectory, TumRoundTripKeepsPosesAndMicrosecondStamps) {
  TempDir dir;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  Trajectory t;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Quaternionf q = Eigen::Quaternionf::UnitRandom();
    t.poses.push_back(
        {1311868164.363181 + i / 30.0, poseFromTranslationQuaternion({u(rng), u(rng), u(rng)}, q)});
  }
  writeTumTrajectory(dir / "t.txt", t);
  const Trajectory back = readTumTrajectory(dir / "t.txt");
  ASSERT_EQ(back.size(), t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(back.poses[i].stamp_s, t.poses[i].stamp_s, 0.5e-6);  // written with 6 decimals
    EXPECT_TRUE(back.poses[i].T_W_C.translation().isApprox(t.poses[i].T_W_C.translation(), 0.0f))
        << "translations are written exactly";
    // The quaternion is written exactly, then renormalised: rotation within float rounding.
    EXPECT_LT((back.poses[i].T_W_C.linear() - t.poses[i].T_W_C.linear()).cwiseAbs().maxCoeff(),
              1e-6f);
  }
}

TEST(Trajectory, PosesOutOfTimeOrderAreNeverWritten) {
  // The reader refuses stamps that go backwards; the writer refuses to make such a file.
  TempDir dir;
  Trajectory t;
  t.poses.push_back({2.0, Pose::Identity()});
  t.poses.push_back({1.0, Pose::Identity()});
  EXPECT_THROW(writeTumTrajectory(dir / "t.txt", t), std::invalid_argument);
  EXPECT_FALSE(std::filesystem::exists(dir / "t.txt"));
  t.poses[1].stamp_s = 2.0;  // equal stamps read back, so they are written
  writeTumTrajectory(dir / "t.txt", t);
  EXPECT_EQ(readTumTrajectory(dir / "t.txt").size(), 2u);
}

TEST(Trajectory, ReadsCommentsBlankLinesCommasAndTumConvention) {
  TempDir dir;
  // A 90-degree turn about z: qz = qw = sqrt(0.5). The camera sits at (1, 2, 3).
  writeBytes(dir / "t.txt",
             "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n\n"
             "1.0 1 2 3 0 0 0.7071068 0.7071068\n"
             "2.5,1,2,4,0,0,0,1\r\n");
  const Trajectory t = readTumTrajectory(dir / "t.txt");
  ASSERT_EQ(t.size(), 2u);
  const Eigen::Vector3f p_W = t.poses[0].T_W_C * Eigen::Vector3f(1, 0, 0);
  EXPECT_TRUE(p_W.isApprox(Eigen::Vector3f(1, 3, 3), 1e-6f)) << p_W.transpose();
  EXPECT_DOUBLE_EQ(t.durationS(), 1.5);
  EXPECT_NEAR(t.pathLengthM(), 1.0, 1e-9);
}

TEST(Trajectory, ViewUpIsTheRoomsUpForACameraTiltedDownAndTurnedAllAround) {
  // A camera 1.5 m up, tilted 35 degrees down, turned to 12 headings around the room's z (up):
  // the tilts cancel out, and up in its images is the room's up on average.
  Trajectory t;
  for (int i = 0; i < 12; ++i) {
    const float heading = static_cast<float>(i) * 0.5236f;
    // Camera frame: x right, y down, z forward; level forward is (cos, sin, 0) in the room.
    const Eigen::Matrix3f level =
        (Eigen::Matrix3f() << std::sin(heading), 0.0f, std::cos(heading),  //
         -std::cos(heading), 0.0f, std::sin(heading),                       //
         0.0f, -1.0f, 0.0f)
            .finished();
    Pose p = Pose::Identity();
    p.linear() = level * Eigen::AngleAxisf(-0.61f, Eigen::Vector3f::UnitX()).toRotationMatrix();
    p.translation() = Eigen::Vector3f(0.0f, 0.0f, 1.5f);
    t.poses.push_back({static_cast<double>(i), p});
  }
  const std::optional<Eigen::Vector3f> up = viewUp(t);
  ASSERT_TRUE(up.has_value());
  EXPECT_NEAR(up->z(), 1.0f, 1e-5f);
  // One pose alone (looking along x): its own image up, 35 degrees from the room's, leaning
  // towards where it looks.
  t.poses.resize(1);
  ASSERT_NEAR(t.poses[0].T_W_C.linear().col(2).z(), -std::sin(0.61f), 1e-5f);  // looks down
  EXPECT_TRUE(viewUp(t)->isApprox(Eigen::Vector3f(std::sin(0.61f), 0.0f, std::cos(0.61f)), 1e-5f));
  EXPECT_FALSE(viewUp(Trajectory{}).has_value());
}

TEST(Trajectory, BadFilesGiveErrorsWithLineNumbers) {
  TempDir dir;
  writeBytes(dir / "seven.txt", "# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n");
  expectReadError(dir / "seven.txt", "line 3: expected 8 numbers");
  writeBytes(dir / "word.txt", "1 0 0 zero 0 0 0 1\n");
  expectReadError(dir / "word.txt", "line 1: 'zero' is not a number");
  writeBytes(dir / "nan.txt", "1 0 nan 0 0 0 0 1\n");
  expectReadError(dir / "nan.txt", "line 1: contains NaN");
  writeBytes(dir / "back.txt", "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n");
  expectReadError(dir / "back.txt", "line 2: time stamp");
  writeBytes(dir / "quat.txt", "1 0 0 0 0 0 0 2\n");
  expectReadError(dir / "quat.txt", "has norm 2");
  writeBytes(dir / "huge.txt", "1 1e39 0 0 0 0 0 1\n");
  expectReadError(dir / "huge.txt", "line 1: a coordinate is too large");
  writeBytes(dir / "comments.txt", "# nothing\n");
  expectReadError(dir / "comments.txt", "contains no poses");
  writeBytes(dir / "empty.txt", "");
  expectReadError(dir / "empty.txt", "the file is empty");
  expectReadError(dir / "absent.txt", "no such file");
}

}  // namespace
}  // namespace objscan
