#include "moslam/io/tum.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;

using test::ScratchDir;

void WriteTextFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

bool BitEqual(const Vector3& a, const Vector3& b) {
  return std::memcmp(a.data(), b.data(), 3 * sizeof(double)) == 0;
}

// Converting a rotation to a quaternion and back rounds: a few units in the last place.
constexpr double kQuaternionRoundingTol = 10 * std::numeric_limits<double>::epsilon();

void ExpectInvalid(const fs::path& path, const std::string& needle) {
  try {
    ReadTumTrajectory(path.string());
    ADD_FAILURE() << "expected InvalidInputError";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(Tum, WritesOneFilePerRobotAndKindAndReadsBack) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  const auto random_pose = [&] {
    Vector6 xi;
    for (int i = 0; i < 6; ++i) xi[i] = 2.0 * n(rng);
    return SE3::Exp(xi);
  };
  Values values;
  for (std::uint64_t i = 0; i < 6; ++i) values[Key::Pose(0, i)] = random_pose();
  for (std::uint64_t i = 0; i < 3; ++i) values[Key::Pose(2, i)] = random_pose();
  values[Key::Object(2, 0)] = random_pose();
  values[Key::Object(2, 7)] = random_pose();

  const fs::path dir = ScratchDir() / "tum";
  const std::vector<std::string> paths = WriteTumTrajectories(dir.string(), values);
  EXPECT_EQ(paths, (std::vector<std::string>{(dir / "robot_0.tum").string(),
                                             (dir / "robot_2.tum").string(),
                                             (dir / "robot_2_objects.tum").string()}));

  const Values r0 = ReadTumTrajectory(paths[0], 0);
  ASSERT_EQ(r0.size(), 6u);
  for (std::uint64_t i = 0; i < 6; ++i) {
    const SE3& expected = values.at(Key::Pose(0, i));
    const SE3& got = r0.at(Key::Pose(0, i));
    EXPECT_TRUE(BitEqual(expected.translation(), got.translation()));
    EXPECT_LE((expected.rotation().matrix() - got.rotation().matrix()).cwiseAbs().maxCoeff(),
              kQuaternionRoundingTol);
  }
  const Values r2 = ReadTumTrajectory(paths[1], 2);
  EXPECT_EQ(r2.size(), 3u);
  EXPECT_EQ(r2.begin()->first, Key::Pose(2, 0));

  // Objects in index order, the index as timestamp.
  std::ifstream in(paths[2]);
  std::string line1, line2;
  std::getline(in, line1);
  std::getline(in, line2);
  EXPECT_EQ(line1.rfind("0 ", 0), 0u) << line1;
  EXPECT_EQ(line2.rfind("7 ", 0), 0u) << line2;
  const Values objects = ReadTumTrajectory(paths[2], 2);
  ASSERT_EQ(objects.size(), 2u);
  EXPECT_TRUE(BitEqual(objects.at(Key::Pose(2, 1)).translation(),
                       values.at(Key::Object(2, 7)).translation()));
}

TEST(Tum, ReadsCommentsBlankLinesAndNormalisesQuaternions) {
  const fs::path path = ScratchDir() / "t.tum";
  WriteTextFile(path,
                "# timestamp tx ty tz qx qy qz qw\n\n1.5 1 2 3 0 0 0 2\n"
                "2.5 4 5 6 0 0 1 1  # comment\n");
  const Values v = ReadTumTrajectory(path.string(), 1);
  ASSERT_EQ(v.size(), 2u);
  EXPECT_EQ(v.at(Key::Pose(1, 0)).translation(), Vector3(1, 2, 3));
  EXPECT_TRUE(v.at(Key::Pose(1, 0)).rotation().matrix().isApprox(Matrix3::Identity(), 1e-15));
  Matrix3 rz90;
  rz90 << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((v.at(Key::Pose(1, 1)).rotation().matrix() - rz90).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Tum, RejectsMalformedLinesNamingTheLine) {
  const fs::path dir = ScratchDir();
  WriteTextFile(dir / "count.tum", "0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n");
  ExpectInvalid(dir / "count.tum", "count.tum:2: expected 8 fields");
  WriteTextFile(dir / "nan.tum", "# header\n0 0 nan 0 0 0 0 1\n");
  ExpectInvalid(dir / "nan.tum", "nan.tum:2:");
  ExpectInvalid(dir / "nan.tum", "NaN");
  WriteTextFile(dir / "word.tum", "0 0 0 0 0 0 0 1x\n");
  ExpectInvalid(dir / "word.tum", "word.tum:1: '1x' is not a number");
  WriteTextFile(dir / "zero.tum", "0 0 0 0 0 0 0 0\n");
  ExpectInvalid(dir / "zero.tum", "zero.tum:1: quaternion");
  ExpectInvalid(dir / "missing.tum", "cannot open");
  EXPECT_THROW(ReadTumTrajectory((dir / "count.tum").string(), kMaxRobots), InvalidInputError);
}

TEST(Tum, WriteFailureNamesThePath) {
  const fs::path blocker = ScratchDir() / "file";
  WriteTextFile(blocker, "not a folder");
  try {
    WriteTumTrajectories((blocker / "sub").string(), Values{{Key::Pose(0, 0), SE3()}});
    FAIL() << "expected moslam::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find((blocker / "sub").string()), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace moslam
