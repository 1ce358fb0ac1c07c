#include "objscan/core/trajectory.h"

#include <gtest/gtest.h>

#include <random>

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
